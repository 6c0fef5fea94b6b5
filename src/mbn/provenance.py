"""Where a result came from: the code that made it and the software it ran on.

Every file a run writes about itself (``run.json``, ``results.json``, ``sweep.json``, controller
files) records :func:`provenance`:

- ``code`` (:func:`code_identity`): the package version; ``package_sha256``, a content hash of
  the package's files (their paths and bytes); and where the code came from — ``source: "git"``
  with the ``commit`` and whether the work tree was ``dirty``, when ``mbn`` runs from a git
  checkout (an editable install), or ``source: "package"`` when it is installed from a wheel or
  an sdist (the version and the hash then identify it);
- ``versions`` (:func:`environment`): Python, JAX, jaxlib, NumPy, optax, matplotlib, the
  operating system and the JAX backend.

Two runs were made by the same code when their ``package_sha256`` agree: a commit that changes
only documentation or tests leaves it as it is, an edit to a module changes it whether or not it
is committed. ``--resume``, ``--reuse`` and a resumed sweep compare it (:func:`code_difference`)
and refuse code that differs unless ``--allow-other-code`` is given (``docs/provenance.md``).
"""

from __future__ import annotations

import functools
import hashlib
import platform
import shutil
import subprocess
from pathlib import Path
from typing import Any

from mbn._version import __version__

__all__ = [
    "code_difference",
    "code_identity",
    "describe_code",
    "environment",
    "package_sha256",
    "provenance",
]

#: The package's folder (``src/mbn`` in a checkout, ``site-packages/mbn`` when installed).
PACKAGE_DIR = Path(__file__).resolve().parent
#: Git is asked at most this long (seconds) before the checkout is taken as unknown.
_GIT_TIMEOUT = 10.0


def _package_files(root: Path) -> list[Path]:
    """The files of the package that a wheel ships: everything but compiled bytecode."""
    return sorted(
        p
        for p in root.rglob("*")
        if p.is_file() and "__pycache__" not in p.parts and p.suffix not in {".pyc", ".pyo"}
    )


@functools.cache
def package_sha256(root: Path = PACKAGE_DIR) -> str:
    """SHA-256 over the package's files (each one's path relative to ``root``, then its bytes),
    in sorted order: the same for a checkout and for the wheel built from it."""
    digest = hashlib.sha256()
    for path in _package_files(root):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0")
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()


def _git(top: Path, *args: str) -> str | None:
    git = shutil.which("git")
    if git is None:
        return None
    try:
        done = subprocess.run(
            [git, "-C", str(top), *args],
            capture_output=True,
            text=True,
            timeout=_GIT_TIMEOUT,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    return done.stdout if done.returncode == 0 else None


def _checkout(package: Path) -> Path | None:
    """The top of the git checkout the package runs from (``TOP/src/mbn``), or None."""
    top = package.parent.parent
    if package.parent.name != "src" or not (top / "pyproject.toml").is_file():
        return None
    return top if (top / ".git").exists() else None


def code_identity() -> dict[str, Any]:
    """The code that runs now (module docstring): ``version``, ``package_sha256``, ``source``
    and, from a git checkout, ``commit`` and ``dirty`` (asked once a process; a copy)."""
    return dict(_code_identity())


@functools.cache
def _code_identity() -> dict[str, Any]:
    identity: dict[str, Any] = {
        "version": __version__,
        "package_sha256": package_sha256(),
        "source": "package",
        "commit": None,
        "dirty": None,
    }
    top = _checkout(PACKAGE_DIR)
    if top is not None:
        commit = _git(top, "rev-parse", "HEAD")
        status = _git(top, "status", "--porcelain", "--untracked-files=normal")
        if commit is not None and status is not None:
            identity.update(source="git", commit=commit.strip(), dirty=bool(status.strip()))
    return identity


@functools.cache
def environment() -> dict[str, str]:
    """Versions of what results depend on: ``mbn``, Python, JAX, jaxlib, NumPy, optax,
    matplotlib, the operating system (``os``) and the JAX backend (``platform``)."""
    from importlib.metadata import version

    import jax
    import jaxlib
    import numpy as np
    import optax

    return {
        "mbn": __version__,
        "python": platform.python_version(),
        "jax": jax.__version__,
        "jaxlib": jaxlib.__version__,
        "numpy": np.__version__,
        "optax": optax.__version__,
        "matplotlib": version("matplotlib"),
        "os": platform.platform(),
        "platform": jax.default_backend(),
    }


def provenance() -> dict[str, Any]:
    """``{"code": code_identity(), "versions": environment()}``."""
    return {"code": code_identity(), "versions": dict(environment())}


def describe_code(code: Any) -> str:
    """A recorded code identity in a few words: ``mbn 0.2.0 at commit 1a2b3c4d (dirty)``,
    ``mbn 0.2.0 (package 5e6f7a8b)``."""
    if not isinstance(code, dict):
        return "code not recorded"
    version = code.get("version", "?")
    commit = code.get("commit")
    if isinstance(commit, str) and commit:
        dirty = " with uncommitted changes" if code.get("dirty") else ""
        return f"mbn {version} at commit {commit[:10]}{dirty}"
    sha = code.get("package_sha256")
    return f"mbn {version} (package {str(sha)[:10]})"


def code_difference(recorded: Any, current: dict[str, Any] | None = None) -> str | None:
    """Why the code ``recorded`` in a file is not the code that runs now (``current``,
    default :func:`code_identity`), as a few words for one line; None when it is the same
    (the same ``package_sha256``)."""
    current = code_identity() if current is None else current
    if not isinstance(recorded, dict) or not isinstance(recorded.get("package_sha256"), str):
        return f"it does not record the code that made it; this is {describe_code(current)}"
    if recorded["package_sha256"] == current["package_sha256"]:
        return None
    then, now = describe_code(recorded), describe_code(current)
    if then == now:  # one commit, other uncommitted changes
        then += f", package {recorded['package_sha256'][:10]}"
        now += f", package {current['package_sha256'][:10]}"
    return f"made by {then}; this is {now}"
