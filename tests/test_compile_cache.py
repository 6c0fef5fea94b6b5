"""The persistent compilation cache: where it is, how it is turned off, and that a command
fills it and a second run of the command gives the same output from it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from mbn.compile_cache import VARIABLE, cache_dir, enable


def test_the_folder_follows_the_variable_then_xdg_then_home():
    assert cache_dir({VARIABLE: "/x/y"}) == Path("/x/y")
    assert cache_dir({VARIABLE: "~/c"}) == Path("~/c").expanduser()
    assert cache_dir({"XDG_CACHE_HOME": "/xdg"}) == Path("/xdg/mbn/jax")
    assert cache_dir({}) == Path("~/.cache/mbn/jax").expanduser()
    for off in ("off", "OFF", "0", "no", "false", "none"):
        assert cache_dir({VARIABLE: off}) is None


def test_off_or_unwritable_leaves_it_off_and_a_users_jax_folder_is_kept(tmp_path):
    assert enable({VARIABLE: "off"}) is None
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert enable({VARIABLE: str(blocker / "sub")}) is None  # cannot be created
    assert enable({"JAX_COMPILATION_CACHE_DIR": "/mine", VARIABLE: "off"}) == Path("/mine")


def _drive(tmp_path: Path, cache: str, name: str) -> tuple[subprocess.CompletedProcess, Path]:
    out = tmp_path / name
    env = {**os.environ, VARIABLE: cache}
    cmd = [sys.executable, "-m", "mbn", "drive", "--start", "0,0,0", "--cmd", "0.3,0.5"]
    cmd += ["--seconds", "3", "--out", str(out)]
    return subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300), out


def test_a_command_fills_the_cache_and_a_second_run_reads_the_same_result(tmp_path):
    cache = tmp_path / "cache"
    first, out1 = _drive(tmp_path, str(cache), "a.csv")
    assert first.returncode == 0, first.stderr
    entries = sorted(p.name for p in cache.iterdir() if not p.name.startswith("."))
    assert entries, "the command cached nothing"
    second, out2 = _drive(tmp_path, str(cache), "b.csv")
    assert second.returncode == 0, second.stderr
    assert out1.read_bytes() == out2.read_bytes()
    off, out3 = _drive(tmp_path, "off", "c.csv")
    assert off.returncode == 0 and out3.read_bytes() == out1.read_bytes()
