"""Test configuration: float64 by default (tests that need float32 ask for it explicitly), and
one persistent compilation cache for the session (``mbn.compile_cache``), fresh for each
session and shared with the commands the tests start (they inherit ``MBN_COMPILE_CACHE``), so
that a test compiles again only what no earlier test of the session compiled.

The suite runs on every core (pytest-xdist, ``-n auto`` in ``pyproject.toml``; ``-n 0`` runs it
in one process). The workers share the session's compilation cache, which the first process
creates (the workers inherit its variable) and removes at the end.

A run that several workers' tests read (the session's quick reproduction, ``quick_run``, and the
``im_full`` stage on it) is made once per session whichever worker asks first (:func:`once`; the
others wait for it and read the same folder). The workers take whole modules (``--dist
loadscope``), so that a fixture that only one module reads (an ablation or noise stage on that
run, a contest) is made once too. (``--dist loadgroup`` with ``xdist_group`` marks would group
finer, but under pytest 9 with pytest-xdist 3.8 it groups nothing: the group suffix it gives a
test's id is lost, and the marked tests went to both workers, each making the fixture.)"""

import fcntl
import json
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax

from mbn import compile_cache

jax.config.update("jax_enable_x64", True)

#: Set by the first process of a session for the workers it starts.
_SESSION_CACHE = "MBN_TEST_SESSION_COMPILE_CACHE"
_OWNER = _SESSION_CACHE not in os.environ
if _OWNER:
    os.environ[_SESSION_CACHE] = tempfile.mkdtemp(prefix="mbn-test-compile-cache-")
_CACHE = os.environ[_SESSION_CACHE]
os.environ[compile_cache.VARIABLE] = _CACHE
os.environ.pop("JAX_COMPILATION_CACHE_DIR", None)
compile_cache.enable()


def once(tmp_path_factory, worker_id: str, name: str, build: Callable[[Path], Any]) -> Any:
    """``build(folder)`` run once per session, whichever worker asks first, and its value (JSON)
    for every worker: the others wait on a lock in the session's temporary folder, which the
    workers of one session share (pytest-xdist's documented way to make a session fixture once).
    Without workers (``-n 0``) it is simply ``build`` in a fresh folder (its value read back
    from JSON all the same)."""
    if worker_id == "master":
        return json.loads(json.dumps(build(tmp_path_factory.mktemp(name))))
    root = tmp_path_factory.getbasetemp().parent / f"once-{name}"
    root.mkdir(exist_ok=True)
    done = root / "value.json"
    with open(root / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if done.exists():
            return json.loads(done.read_text())
        folder = root / "data"
        shutil.rmtree(folder, ignore_errors=True)  # a worker that failed building it
        folder.mkdir()
        value = build(folder)
        done.write_text(json.dumps(value))
        return value


def pytest_sessionfinish(session, exitstatus):
    if _OWNER:
        shutil.rmtree(_CACHE, ignore_errors=True)
