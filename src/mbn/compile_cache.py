"""A persistent cache of compiled programs, so that a second run (a sweep's next seed, a resumed
run, the next ``mbn evaluate``) does not compile again what an earlier one compiled.

JAX compiles every rollout, DE step and test it meets for its shapes; a quick reproduction spends
about a third of its time so, a full one tens of seconds. :func:`enable` points JAX's persistent
compilation cache (``jax_compilation_cache_dir``) at a folder, which the command line does at
start and ``mbn sweep`` in each seed's task. A cached program is the program XLA would compile
again: the results are the same bit for bit (``docs/speed.md``).

Where: ``$MBN_COMPILE_CACHE`` if set (``off`` turns the cache off), else
``$XDG_CACHE_HOME/mbn/jax`` (``~/.cache/mbn/jax``). A ``JAX_COMPILATION_CACHE_DIR`` set by the
user is left as it is. A folder that cannot be created leaves the cache off, silently: it only
saves time. Delete the folder to clear it.
"""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Mapping
from pathlib import Path

__all__ = ["MAX_BYTES", "MIN_COMPILE_SECONDS", "VARIABLE", "cache_dir", "enable"]

#: The variable naming the cache's folder, or ``off``.
VARIABLE = "MBN_COMPILE_CACHE"
#: Values of :data:`VARIABLE` that turn the cache off.
OFF = ("off", "0", "no", "false", "none")
#: Programs compiled faster than this are not cached (JAX's default is 1 s; the time a warm
#: cache saves a quick reproduction, ``docs/speed.md``, was measured at 0.1 s).
MIN_COMPILE_SECONDS = 0.1
#: The cache's size bound, where the file lock JAX needs to bound it (and to let several
#: processes, a sweep's seeds, share the folder safely) is installed (``filelock``, which Ray
#: brings); else unbounded, as JAX has it. A full reproduction adds about 4 MB (76 programs).
MAX_BYTES = 2 * 1024**3


def cache_dir(env: Mapping[str, str] | None = None) -> Path | None:
    """The cache's folder by ``env`` (default ``os.environ``), or None when it is off."""
    env = os.environ if env is None else env
    value = env.get(VARIABLE, "").strip()
    if value.lower() in OFF and value:
        return None
    if value:
        return Path(value).expanduser()
    base = env.get("XDG_CACHE_HOME", "").strip() or str(Path("~/.cache").expanduser())
    return Path(base) / "mbn" / "jax"


def enable(env: Mapping[str, str] | None = None) -> Path | None:
    """Turn JAX's persistent compilation cache on in :func:`cache_dir`; the folder used, or None
    (off by ``env``, or the folder cannot be created). Call before the first computation."""
    env = os.environ if env is None else env
    own = env.get("JAX_COMPILATION_CACHE_DIR", "").strip()
    if own:
        return Path(own)
    path = cache_dir(env)
    if path is None:
        return None
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    if not os.access(path, os.W_OK | os.X_OK):
        return None
    import jax

    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_SECONDS)
    if importlib.util.find_spec("filelock") is not None:
        jax.config.update("jax_compilation_cache_max_size", MAX_BYTES)
    return path
