"""One quick run of ``mbn reproduce`` (seed 3) shared by the tests of this folder and below: run
once per session, started in the background as soon as the tests that read it are collected
(``tests.conftest.start_early``)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from tests.conftest import start_early, wait_early


def reproduce(*args: str, **kw) -> subprocess.CompletedProcess:
    """``mbn reproduce --quiet ARGS`` in a fresh process."""
    return subprocess.run(
        [sys.executable, "-m", "mbn", "reproduce", "--quiet", *args],
        capture_output=True,
        text=True,
        timeout=600,
        **kw,
    )


#: The session's quick run, started early (``tests.conftest.start_early``).
QUICK = [sys.executable, "-m", "mbn", "reproduce", "--quiet", "--quick", "--out", "{out}",
         "--seed", "3"]  # fmt: skip


def pytest_collection_modifyitems(config, items):
    # the quick run starts as soon as tests that read it are collected, beside the first tests
    if any("quick_run" in getattr(item, "fixturenames", ()) for item in items):
        start_early("quick", QUICK)


@pytest.fixture(scope="session")
def quick_run():
    """``(folder, seconds)`` of ``mbn reproduce --quick --seed 3``, started when the tests were
    collected (tests copy the folder before they change anything in it)."""
    start_early("quick", QUICK)  # a test selected without the others' collection hook
    return wait_early("quick")
