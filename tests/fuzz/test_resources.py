"""The resource cases (slow: ``pytest -m slow``): each command on the worlds that used to exhaust
memory or time runs in a fresh process under 1 GB of peak memory and 30 s (``docs/world.md``,
"Worlds that are not grids"; ``docs/bad-input.md``). The inputs are generated here."""

from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

DOCS = Path(__file__).resolve().parents[2] / "docs" / "mazes.md"

_MEASURE = """
import sys, runpy
sys.argv = ["mbn", *sys.argv[1:]]
try:
    runpy.run_module("mbn", run_name="__main__")
except SystemExit as exc:
    code = exc.code
else:
    code = 0
status = open("/proc/self/status").read()
hwm = [line for line in status.splitlines() if line.startswith("VmHWM:")][0]
print("HWM", int(hwm.split()[1]) // 1024, file=sys.stderr)
sys.exit(code)
"""


def _run(*argv: str) -> tuple[float, int]:
    """Wall seconds and peak memory (MB) of ``mbn ARGV`` in a fresh process."""
    t0 = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", _MEASURE, *argv], capture_output=True, text=True, timeout=120
    )
    seconds = time.perf_counter() - t0
    assert done.returncode == 0, done.stderr
    mb = int(re.findall(r"HWM (\d+)", done.stderr)[-1])
    return seconds, mb


def _docs_example(tmp_path: Path) -> Path:
    block = re.search(r"```toml\n(.*?)```", DOCS.read_text(), re.S)
    assert block is not None
    path = tmp_path / "docs.toml"
    path.write_text(block.group(1))
    return path


def _fine_room(tmp_path: Path) -> Path:
    path = tmp_path / "fine.toml"
    path.write_text(
        "[[free]]\nxmin = 0\nxmax = 6.01\nymin = 0\nymax = 4.37\n"
        "[[wall]]\nxmin = 2.03\nxmax = 2.41\nymin = 0\nymax = 1.79\n"
        "[[start]]\nx = 0.6\ny = 0.6\ntheta = 0\n"
    )
    return path


def _two_walls(tmp_path: Path) -> Path:
    path = tmp_path / "far.toml"
    path.write_text(
        "[[wall]]\nxmin = 0\nxmax = 1\nymin = 0\nymax = 0.1\n"
        "[[wall]]\nxmin = 2000\nxmax = 2001\nymin = 0\nymax = 0.1\n"
    )
    return path


@pytest.mark.parametrize("world", ["docs", "fine", "far"])
def test_sonar_and_drive_on_worlds_that_are_not_grids(tmp_path, world):
    maze = {"docs": _docs_example, "fine": _fine_room, "far": _two_walls}[world](tmp_path)
    poses = tmp_path / "poses.csv"
    poses.write_text("x,y,theta\n0.6,0.6,0\n1.0,0.5,1.0\n")
    seconds, mb = _run(
        "sonar", "--maze", str(maze), "--poses", str(poses), "--out", str(tmp_path / "s.csv")
    )
    assert seconds < 30 and mb < 1024, (seconds, mb)
    seconds, mb = _run(
        "drive",
        "--maze",
        str(maze),
        "--start",
        "0.6,0.6,0",
        "--cmd",
        "0.3,0.5",
        "--seconds",
        "2",
        "--out",
        str(tmp_path / "d.csv"),
    )
    assert seconds < 30 and mb < 1024, (seconds, mb)


def test_drive_a_million_steps_without_a_maze(tmp_path):
    out = tmp_path / "big.csv"
    seconds, mb = _run(
        "drive", "--start", "0,0,0", "--cmd", "0.3,0.5", "--seconds", "100000", "--out", str(out)
    )
    assert seconds < 30 and mb < 1024, (seconds, mb)
    with out.open() as handle:
        assert sum(1 for _ in handle) == 1_000_002  # header + the start + 10^6 moves


def test_a_2000_by_2000_maze_loads_under_1_gb(tmp_path):
    n = 2000
    rows = ["#" * n]
    for r in range(1, n - 1):
        rows.append("#" + "".join("." if r % 2 or c % 2 else "#" for c in range(1, n - 1)) + "#")
    rows.append("#" * n)
    path = tmp_path / "huge.maze"
    path.write_text("cell = 1.2\n" + "\n".join(rows) + "\n")
    code = (
        "import time; t = time.perf_counter(); from mbn.world.mazes.load import load_maze; "
        f"m = load_maze({str(path)!r}); s = time.perf_counter() - t; "
        "hwm = [l for l in open('/proc/self/status') if l.startswith('VmHWM')][0]; "
        "print(s, int(hwm.split()[1]) // 1024, m.walls.shape[0])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    seconds, mb, walls = out.stdout.split()
    assert float(seconds) < 30 and int(mb) < 1024 and int(walls) > 900_000, out.stdout
