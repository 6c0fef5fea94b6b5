"""One quick run of ``mbn reproduce`` (seed 3) shared by the tests of this folder and below (made
once per session, on whichever worker asks first: ``tests.conftest.once``)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.conftest import once


def reproduce(*args: str, **kw) -> subprocess.CompletedProcess:
    """``mbn reproduce --quiet ARGS`` in a fresh process."""
    return subprocess.run(
        [sys.executable, "-m", "mbn", "reproduce", "--quiet", *args],
        capture_output=True,
        text=True,
        timeout=600,
        **kw,
    )


@pytest.fixture(scope="session")
def quick_run(tmp_path_factory, worker_id):
    """``(folder, seconds)`` of ``mbn reproduce --quick --seed 3`` (tests copy the folder before
    they change anything in it)."""

    def build(folder: Path) -> list:
        out = folder / "run"
        t0 = time.perf_counter()
        proc = reproduce("--quick", "--out", str(out), "--seed", "3")
        assert proc.returncode == 0, proc.stderr
        return [str(out), time.perf_counter() - t0]

    out, seconds = once(tmp_path_factory, worker_id, "quick", build)
    return Path(out), seconds
