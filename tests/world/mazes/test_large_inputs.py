"""Large inputs stay linear: a 1000 x 1000-cell maze loads in seconds and under 1 GB, a 300 x 300
open room draws in seconds, a small PNG that decodes to gigapixels is refused in one line. The
inputs are generated here (nothing big in git)."""

from __future__ import annotations

import struct
import subprocess
import sys
import textwrap
import time
import zlib
from pathlib import Path

import numpy as np
import pytest

from mbn.cli.main import main
from mbn.world.mazes import validate
from mbn.world.mazes.model import Maze


def _grid_maze(path: Path, n: int, open_room: bool = False) -> Path:
    rows = ["#" * n]
    for r in range(1, n - 1):
        if open_room:
            rows.append("#" + "." * (n - 2) + "#")
        else:
            rows.append(
                "#" + "".join("." if r % 2 or c % 2 else "#" for c in range(1, n - 1)) + "#"
            )
    rows.append("#" * n)
    rows[1] = rows[1][:1] + ">" + rows[1][2:]
    path.write_text("cell = 1.2\n" + "\n".join(rows) + "\n")
    return path


def _peak(code: str) -> tuple[float, float]:
    """Wall seconds and peak resident memory (MB, the process's own high-water mark: ``VmHWM``;
    ``ru_maxrss`` can carry the parent's) of ``code`` in a fresh Python."""
    script = textwrap.dedent(
        """
        import time
        t = time.perf_counter()
        {code}
        status = open("/proc/self/status").read()
        hwm = [line for line in status.splitlines() if line.startswith("VmHWM:")][0]
        print(time.perf_counter() - t, int(hwm.split()[1]) / 1024)
        """
    ).format(code=code)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    seconds, mb = out.stdout.split()[-2:]
    return float(seconds), float(mb)


@pytest.mark.slow  # a bound on time and memory; the refusals of large inputs stay in CI
def test_a_1000_by_1000_maze_loads_in_seconds_and_under_1_gb(tmp_path):
    path = _grid_maze(tmp_path / "big.maze", 1000)
    seconds, mb = _peak(
        f"from mbn.world.mazes.load import load_maze; m = load_maze({str(path)!r}); "
        "assert m.walls.shape[0] > 200_000"
    )
    assert seconds < 30 and mb < 1024, (seconds, mb)


def test_a_300_by_300_open_room_draws_in_seconds(tmp_path, capsys):
    path = _grid_maze(tmp_path / "room.maze", 300, open_room=True)
    t0 = time.perf_counter()
    assert main(["show-maze", str(path), "--out", str(tmp_path / "room.png")]) == 0
    assert time.perf_counter() - t0 < 30
    assert (tmp_path / "room.png").stat().st_size > 5_000


def _brute_free(walls: np.ndarray, bounds: tuple[float, float, float, float]) -> bool:
    x0, x1, y0, y1 = bounds
    xs = np.unique(np.clip(np.r_[x0, x1, walls[:, 0], walls[:, 1]], x0, x1))
    ys = np.unique(np.clip(np.r_[y0, y1, walls[:, 2], walls[:, 3]], y0, y1))
    for cx in (xs[:-1] + xs[1:]) / 2:
        for cy in (ys[:-1] + ys[1:]) / 2:
            inside = (
                (walls[:, 0] < cx) & (cx < walls[:, 1]) & (walls[:, 2] < cy) & (cy < walls[:, 3])
            )
            if not inside.any():
                return True
    return False


@pytest.mark.parametrize("path", ["direct", "sweep"])
def test_the_free_space_check_is_exact_on_random_walls(monkeypatch, path):
    if path == "sweep":
        monkeypatch.setattr(validate, "_DIRECT_CELLS", 0)
    rng = np.random.default_rng(5)
    seen = set()
    for _ in range(300):
        # solid cells of a 4 x 4 box (often all of them), as unit squares and a few larger
        # random rectangles that overlap them
        solid = np.argwhere(rng.random((4, 4)) < 0.9).astype(float)
        cells = np.stack([solid[:, 0], solid[:, 0] + 1, solid[:, 1], solid[:, 1] + 1], 1)
        lo = rng.integers(0, 4, (3, 2)).astype(float)
        size = rng.integers(1, 3, (3, 2)).astype(float)
        extra = np.stack([lo[:, 0], lo[:, 0] + size[:, 0], lo[:, 1], lo[:, 1] + size[:, 1]], 1)
        walls = np.concatenate([cells, extra[: int(rng.integers(0, 4))]])
        bounds = (0.0, 4.0, 0.0, 4.0)
        maze = Maze(name="r", walls=walls, bounds=bounds, outside_is_wall=True)
        expected = _brute_free(walls, bounds)
        assert validate._has_free_space(maze) == expected
        seen.add(expected)
    assert seen == {True, False}


def _png_bomb(path: Path, side: int) -> Path:
    """A grey PNG of ``side`` x ``side`` white pixels: a few hundred kB for tens of megapixels."""
    comp = zlib.compressobj(9)
    row = b"\x00" + b"\xff" * side
    data = b"".join(comp.compress(row) for _ in range(side)) + comp.flush()

    def chunk(kind: bytes, body: bytes) -> bytes:
        crc = zlib.crc32(kind + body) & 0xFFFFFFFF
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", crc)

    header = struct.pack(">IIBBBBB", side, side, 8, 0, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", data) + chunk(b"IEND", b"")
    )
    return path


@pytest.mark.parametrize(("side", "words"), [(5000, "is 5000 x 5000 pixels"), (20000, "decodes")])
def test_a_png_floorplan_that_decodes_to_too_many_pixels_is_refused(tmp_path, capsys, side, words):
    _png_bomb(tmp_path / "plan.png", side)
    assert (tmp_path / "plan.png").stat().st_size < 1_000_000
    world = Path(__file__).resolve().parents[2] / "data" / "stage_world" / "bitmap.world"
    (tmp_path / "w.world").write_text(world.read_text().replace("plus4.png", "plan.png"))
    assert main(["show-maze", str(tmp_path / "w.world"), "--out", str(tmp_path / "w.png")]) == 2
    err = capsys.readouterr().err.strip()
    assert (len(err.splitlines()) == 1 and words in err and "over the limit" in err) or (
        "more pixels than the limit" in err
    ), err
    assert not (tmp_path / "w.png").exists()


def test_show_maze_refuses_a_grid_over_its_limit_up_front(tmp_path, capsys):
    """A 2000 x 2000 grid (4 M cells) is refused from a look at its lines, in a second or two,
    in one line naming the limit; nothing is written."""
    path = _grid_maze(tmp_path / "huge.maze", 2000)
    out = tmp_path / "huge.png"
    t0 = time.perf_counter()
    assert main(["show-maze", str(path), "--out", str(out)]) == 2
    assert time.perf_counter() - t0 < 5
    assert capsys.readouterr().err == (
        f"mbn: error: {path}: a grid of 2000 x 2000 cells; show-maze draws grids of at most "
        "1,000,000 cells (1000 x 1000)\n"
    )
    assert not out.exists()


def test_show_maze_refuses_a_1000_by_1000_checkerboard_from_its_content(tmp_path, capsys):
    """Within the limit, but with no corridor: refused in one line in seconds, not drawn."""
    path = tmp_path / "checker.maze"
    path.write_text("\n".join("".join(".#"[(r + c) % 2] for c in range(1000)) for r in range(1000)))
    t0 = time.perf_counter()
    assert main(["show-maze", str(path), "--out", str(tmp_path / "c.png")]) == 2
    assert time.perf_counter() - t0 < 5
    err = capsys.readouterr().err
    assert err.startswith(f"mbn: error: {path}:1: no corridor: no two free cells side by side")
    assert len(err.splitlines()) == 1


def test_a_700_by_700_maze_draws_in_bounded_time_as_raster_layers():
    """Its 120 000 wall rectangles and decision cells are one raster image each (at most
    RASTER_PIXELS a side, a whole number of pixels a cell), drawn in seconds."""
    from matplotlib.image import AxesImage

    from mbn.viz.maze import RASTER_PIXELS, draw_maze
    from mbn.world.mazes.model import merge_cells

    n = 700
    grid = np.full((n, n), "#")
    grid[1:-1, 1:-1] = np.where(
        (np.arange(1, n - 1)[:, None] % 2 == 1) | (np.arange(1, n - 1)[None, :] % 2 == 1), ".", "#"
    )
    maze = Maze(
        "lattice", merge_cells(grid == "#", 1.2), (0.0, n * 1.2, 0.0, n * 1.2), grid=grid, cell=1.2
    )
    assert len(maze.walls) > 100_000
    t0 = time.perf_counter()
    ax = draw_maze(maze).axes[0]
    assert time.perf_counter() - t0 < 15
    images = {im.get_gid(): im for im in ax.get_images() if isinstance(im, AxesImage)}
    assert set(images) == {"wall", "decision"}
    assert not [p for p in ax.patches if p.get_gid() in ("wall", "decision")]
    wall = images["wall"].get_array()
    assert wall.shape[:2] == (n * (RASTER_PIXELS // n), n * (RASTER_PIXELS // n))
    assert images["wall"].get_extent() == pytest.approx((0.0, n * 1.2, 0.0, n * 1.2))
