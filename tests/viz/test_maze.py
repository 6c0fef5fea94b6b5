"""Pictures of mazes: the figures hold the right geometry and the PNG files are real."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.figure import Figure
from PIL import Image

from mbn.errors import MbnInputError
from mbn.viz.maze import draw_maze, save_maze_png
from mbn.world.mazes.model import Maze


def patches(ax, gid: str) -> list:
    return [p for p in ax.patches if p.get_gid() == gid]


def test_draw_maze_draws_walls_tiles_decision_cells_and_starts(tee):
    fig = draw_maze(tee)
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    walls = patches(ax, "wall")
    got = sorted(
        (p.get_x(), p.get_x() + p.get_width(), p.get_y(), p.get_y() + p.get_height()) for p in walls
    )
    np.testing.assert_allclose(np.array(got), np.array(sorted(map(tuple, tee.walls))))
    # the T's junction (row 1, column 2) is the only decision cell
    (dec,) = patches(ax, "decision")
    assert (dec.get_x(), dec.get_y(), dec.get_width()) == pytest.approx((2.4, 3.6, tee.cell))
    (one,) = patches(ax, "tile1")
    np.testing.assert_allclose(one.get_xy()[:4], tee.tiles[0].corners())
    halves = patches(ax, "tile2")
    assert len(halves) == 2
    assert {tuple(p.get_facecolor()) for p in halves} != {tuple(halves[0].get_facecolor())}
    union = np.concatenate([h.get_xy()[:4] for h in halves])
    corners = tee.tiles[1].corners()
    assert union[:, 0].min() == pytest.approx(corners[:, 0].min())
    assert union[:, 1].max() == pytest.approx(corners[:, 1].max())
    assert len(patches(ax, "start")) == 2
    # numbered from 1, as `mbn evaluate` and the episode panels' titles ("start 1: ok") count
    labels = [t.get_text() for t in ax.texts if t.get_gid() == "start_label"]
    assert labels == ["1", "2"]
    assert len(patches(ax, "frame")) == 4  # outside is wall
    assert ax.get_aspect() == 1.0
    assert ax.get_title() == "tee"


def test_open_maze_has_no_frame_and_no_decision_cells():
    maze = Maze(
        name="open",
        walls=[[0.0, 1.0, 0.0, 3.0], [2.2, 3.2, 0.0, 3.0]],
        bounds=(0.0, 3.2, 0.0, 3.0),
        outside_is_wall=False,
    )
    ax = draw_maze(maze, junctions=True, title="").axes[0]
    assert patches(ax, "frame") == [] and patches(ax, "decision") == []
    assert len(patches(ax, "wall")) == 2
    assert ax.get_title() == ""


def test_save_maze_png_writes_a_real_png(tee, tmp_path):
    out = tmp_path / "tee.png"
    fig = save_maze_png(tee, out, title="a T junction")
    assert isinstance(fig, Figure)
    assert out.stat().st_size > 10_000
    with Image.open(out) as im:
        assert im.format == "PNG"
        assert im.width > 500 and im.height > 500
        pixels = np.asarray(im.convert("RGB"))
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 10  # not a blank picture
    assert not list(tmp_path.glob(".*"))  # no temporary file left behind
    with pytest.raises(MbnInputError, match="does not exist"):
        save_maze_png(tee, tmp_path / "missing" / "x.png")


def test_decision_cells_are_drawn_where_a_moved_or_uneven_grid_lies():
    """fig4 centred on the origin: its decision cells moved with it; the Stage arena (a grid of
    1.2 m corridors and blocks of other widths): each decision cell over its own column and
    row."""
    from mbn.world.junctions import decision_cells
    from mbn.world.mazes.gridify import as_grid_maze
    from mbn.world.mazes.load import load_maze

    f4 = load_maze("fig4")
    moved = Maze("m", f4.walls - [9.0, 9.0, 6.6, 6.6], (-9.0, 9.0, -6.6, 6.6))
    at_origin = sorted((p.get_x(), p.get_y()) for p in patches(draw_maze(f4).axes[0], "decision"))
    ax = draw_maze(as_grid_maze(moved)).axes[0]
    got = sorted((p.get_x() + 9.0, p.get_y() + 6.6) for p in patches(ax, "decision"))
    np.testing.assert_allclose(got, at_origin, atol=1e-9)
    arena = as_grid_maze(load_maze("stage_arena"))
    xs, ys = arena.edges
    rows, cols = np.nonzero(decision_cells(arena))
    want = sorted(
        (xs[c], xs[c + 1] - xs[c], ys[6 - 1 - r], ys[6 - r] - ys[6 - 1 - r])
        for r, c in zip(rows, cols, strict=True)
    )
    drawn = sorted(
        (p.get_x(), p.get_width(), p.get_y(), p.get_height())
        for p in patches(draw_maze(arena).axes[0], "decision")
    )
    assert len(want) == 4 and want[0] == pytest.approx((4.0, 1.2, 4.6, 1.2))  # the T of V1
    np.testing.assert_allclose(drawn, want, atol=1e-9)


def test_many_rectangles_are_one_raster_image_that_covers_the_same_cells(tee, monkeypatch):
    """Above MAX_PATCHES (here 0), walls and decision cells are raster images whose pixels (a
    whole number a cell) cover exactly the wall cells and the decision cell."""
    from mbn.viz import maze as viz_maze

    monkeypatch.setattr(viz_maze, "MAX_PATCHES", 0)
    ax = draw_maze(tee).axes[0]
    images = {im.get_gid(): im for im in ax.get_images()}
    k = viz_maze.RASTER_PIXELS // 5
    wall = np.asarray(images["wall"].get_array())[..., 3] > 0  # row 0 south
    np.testing.assert_array_equal(wall, np.kron((tee.grid == "#")[::-1], np.ones((k, k), bool)))
    decision = np.asarray(images["decision"].get_array())[..., 3] > 0
    assert decision.sum() == k * k and decision[3 * k : 4 * k, 2 * k : 3 * k].all()
    assert images["wall"].get_extent() == pytest.approx(tee.bounds)
