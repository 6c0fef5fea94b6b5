"""Test configuration: float64 by default (tests that need float32 ask for it explicitly), and
one persistent compilation cache for the session (``mbn.compile_cache``), fresh for each
session and shared with the commands the tests start (they inherit ``MBN_COMPILE_CACHE``), so
that a test compiles again only what no earlier test of the session compiled.

The suite runs on every core (pytest-xdist, ``-n auto`` in ``pyproject.toml``; ``-n 0`` runs it
in one process). The workers share the session's compilation cache, which the first process
creates (the workers inherit its variable) and removes at the end, and the tests that use the
session's quick reproduction (``quick_run`` and the fixtures built on it) run on one worker, so
that it is run once (``xdist_group``, with ``--dist loadgroup``)."""

import os
import shutil
import tempfile

import jax
import pytest

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


def pytest_collection_modifyitems(config, items):
    # ``fixturenames`` is the closure: a test using a fixture built on ``quick_run`` has it too
    for item in items:
        if "quick_run" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.xdist_group("quick_run"))


def pytest_sessionfinish(session, exitstatus):
    if _OWNER:
        shutil.rmtree(_CACHE, ignore_errors=True)
