"""One quick run of ``mbn reproduce`` (seed 3) shared by the tests of this folder and below."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest


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
def quick_run(tmp_path_factory):
    """``(folder, seconds)`` of ``mbn reproduce --quick --seed 3``."""
    out = tmp_path_factory.mktemp("quick") / "run"
    t0 = time.perf_counter()
    proc = reproduce("--quick", "--out", str(out), "--seed", "3")
    assert proc.returncode == 0, proc.stderr
    return out, time.perf_counter() - t0
