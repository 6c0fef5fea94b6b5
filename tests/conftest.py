"""Test configuration: float64 by default (tests that need float32 ask for it explicitly), and
one persistent compilation cache for the session (``mbn.compile_cache``), fresh for each
session, for the commands the tests start (they inherit ``MBN_COMPILE_CACHE``): a command
compiles again only what no earlier command of the session compiled. The test processes
themselves do not write to it: each keeps what it compiled in memory, and writing every
program to the disk cost them more than the few that another process could read back (the
suite took 10 % longer with it, ``benchmarks/README.md``).

The suite runs on every core (pytest-xdist, ``-n auto`` in ``pyproject.toml``; ``-n 0`` runs it
in one process). The first process creates the session's compilation cache (the workers and the
commands inherit its variable) and removes it at the end.

A run that several workers' tests read is made once per session: the session's quick
reproduction (``quick_run``) starts in the background when the tests are collected
(:func:`start_early`), and the ``im_full`` stage on it is made by whichever worker asks first
(:func:`once`); the others wait for it and read the same folder. The workers take whole modules
(``--dist loadscope``), so that a fixture that only one module reads (an ablation or noise stage
on that run, a contest) is made once too. (``--dist loadgroup`` with ``xdist_group`` marks
would group finer, but under pytest 9 with pytest-xdist 3.8 it groups nothing: the group suffix
it gives a test's id is lost, and the marked tests went to both workers, each making the
fixture.)"""

import contextlib
import fcntl
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax

from mbn import compile_cache

jax.config.update("jax_enable_x64", True)

#: Set by the first process of a session for the workers it starts.
_SESSION_CACHE = "MBN_TEST_SESSION_COMPILE_CACHE"
#: The session's folder of commands started early (:func:`start_early`), likewise.
_SESSION_EARLY = "MBN_TEST_SESSION_EARLY"
_OWNER = _SESSION_CACHE not in os.environ
if _OWNER:
    os.environ[_SESSION_CACHE] = tempfile.mkdtemp(prefix="mbn-test-compile-cache-")
    os.environ[_SESSION_EARLY] = tempfile.mkdtemp(prefix="mbn-test-early-")
_CACHE = os.environ[_SESSION_CACHE]
_EARLY = Path(os.environ[_SESSION_EARLY])
os.environ[compile_cache.VARIABLE] = _CACHE
os.environ.pop("JAX_COMPILATION_CACHE_DIR", None)

#: Runs the command after ``--`` with its output in LOG, then writes its exit status and
#: seconds to DONE (atomically): the record outlives the process that started it.
_RUNNER = """\
import json, os, subprocess, sys, time
log, done, argv = sys.argv[1], sys.argv[2], sys.argv[4:]
t0 = time.perf_counter()
with open(log, "w") as out:
    code = subprocess.call(argv, stdout=out, stderr=subprocess.STDOUT)
with open(done + ".tmp", "w") as f:
    json.dump({"returncode": code, "seconds": time.perf_counter() - t0}, f)
os.replace(done + ".tmp", done)
"""


def start_early(name: str, argv: list[str]) -> Path:
    """Start ``argv`` (a command line) in the background, once per session, whichever process
    asks first, and return its folder (``out`` inside it is the command's to write): a run
    that many tests read starts when the tests are collected, beside the first tests, instead
    of holding up a worker when a test first needs it (:func:`wait_early`)."""
    folder = _EARLY / name
    try:
        folder.mkdir()
    except FileExistsError:
        return folder  # started by another worker
    argv = [a.replace("{out}", str(folder / "out")) for a in argv]
    proc = subprocess.Popen(
        [sys.executable, "-c", _RUNNER, str(folder / "log"), str(folder / "done"), "--", *argv],
        start_new_session=True,  # ended with its group if the session ends first
        stdin=subprocess.DEVNULL,
    )
    (folder / "pid").write_text(str(proc.pid))
    return folder


def wait_early(name: str, timeout: float = 1800.0) -> tuple[Path, float]:
    """``(out, seconds)`` of the command :func:`start_early` started as ``name``, once it has
    ended; a failure shows the end of its output."""
    folder = _EARLY / name
    deadline = time.monotonic() + timeout
    while not (folder / "done").exists():
        assert folder.exists(), f"{name}: never started"
        assert time.monotonic() < deadline, f"{name}: not done after {timeout:.0f} s"
        time.sleep(0.2)
    done = json.loads((folder / "done").read_text())
    assert done["returncode"] == 0, (folder / "log").read_text()[-3000:]
    return folder / "out", done["seconds"]


def kill_when_written(
    argv: list[str], files: list[Path], timeout: float, settle: float = 0.3
) -> None:
    """Start ``argv`` in a process group of its own, wait until every one of ``files`` exists
    (a checkpoint: the run is in the middle of a stage), then SIGKILL the group; fails if the
    command ended first."""
    proc = subprocess.Popen(
        argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        if all(f.exists() for f in files):
            break
        time.sleep(0.05)
    assert proc.poll() is None, "the command ended before it could be interrupted"
    time.sleep(settle)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


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
        for pid in _EARLY.glob("*/pid"):  # a command still running when the tests ended
            with contextlib.suppress(OSError, ValueError):
                os.killpg(int(pid.read_text()), signal.SIGKILL)
        shutil.rmtree(_CACHE, ignore_errors=True)
        shutil.rmtree(_EARLY, ignore_errors=True)
