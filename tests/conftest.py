"""Test configuration: float64 by default (tests that need float32 ask for it explicitly), and
one persistent compilation cache for the session (``mbn.compile_cache``), fresh for each
session and shared with the commands the tests start (they inherit ``MBN_COMPILE_CACHE``), so
that a test compiles again only what no earlier test of the session compiled."""

import os
import shutil
import tempfile

import jax

from mbn import compile_cache

jax.config.update("jax_enable_x64", True)

_CACHE = tempfile.mkdtemp(prefix="mbn-test-compile-cache-")
os.environ[compile_cache.VARIABLE] = _CACHE
os.environ.pop("JAX_COMPILATION_CACHE_DIR", None)
compile_cache.enable()


def pytest_sessionfinish(session, exitstatus):
    shutil.rmtree(_CACHE, ignore_errors=True)
