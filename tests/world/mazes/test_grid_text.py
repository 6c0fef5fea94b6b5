"""The .maze text-grid reader."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.world.mazes.grid_text import grid_tile_heading, parse_maze_text, read_maze_file
from mbn.world.mazes.model import DEFAULT_TILE_LENGTH


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_small_grid_walls_starts_and_bounds():
    maze = parse_maze_text("#.#\n#^.\n", "m.maze")
    assert maze.grid is not None and maze.grid.dtype == np.dtype("<U1")
    assert maze.grid.tolist() == [["#", ".", "#"], ["#", "^", "."]]
    assert maze.cell == 1.2 and maze.outside_is_wall
    assert maze.bounds == pytest.approx((0.0, 3.6, 0.0, 2.4))
    # column 0 is solid on both lines (one merged rectangle), column 2 only on the top line
    np.testing.assert_allclose(maze.walls, [[0.0, 1.2, 0.0, 2.4], [2.4, 3.6, 1.2, 2.4]])
    np.testing.assert_allclose(maze.starts, [[1.8, 0.6, math.pi / 2]])
    assert maze.name == "m" and maze.source == "m.maze"
    assert maze.is_free(1.8, 1.8) and not maze.is_free(0.6, 1.8) and not maze.is_free(4.0, 1.0)


def test_cell_header_scales_every_coordinate():
    maze = parse_maze_text("cell = 2\n#.\n>.\n", "m.maze")
    assert maze.cell == 2.0
    assert maze.bounds == (0.0, 4.0, 0.0, 4.0)
    np.testing.assert_allclose(maze.walls, [[0.0, 2.0, 2.0, 4.0]])
    np.testing.assert_allclose(maze.starts, [[1.0, 1.0, 0.0]])


def test_start_marks_face_their_compass_directions():
    maze = parse_maze_text("><^v\n", "m.maze")
    np.testing.assert_allclose(maze.starts[:, 2], [0.0, math.pi, math.pi / 2, -math.pi / 2])
    np.testing.assert_allclose(maze.starts[:, 0], [0.6, 1.8, 3.0, 4.2])
    np.testing.assert_allclose(maze.starts[:, 1], 0.6)


def test_ragged_lines_are_padded_with_wall():
    maze = parse_maze_text("..\n.....\n.\n", "m.maze")
    assert maze.grid is not None
    assert ["".join(row) for row in maze.grid] == ["..###", ".....", ".####"]
    np.testing.assert_allclose(maze.walls, [[2.4, 6.0, 2.4, 3.6], [1.2, 6.0, 0.0, 1.2]])


def test_comments_headers_and_blank_lines():
    text = (
        "; a comment before the header\n"
        "\n"
        'name = "tee"   ; the maze\'s name\n'
        "  ; an indented comment\n"
        "cell = 1.5\n"
        "\n"
        ".....\n"
        "; a comment inside the grid\n"
        "##1##\n"
        "##^##\n"
        "\n"
        "; trailing comment and blank lines are ignored\n"
        "\n"
    )
    maze = parse_maze_text(text, "t.maze")
    assert maze.name == "tee" and maze.cell == 1.5
    assert maze.grid is not None and maze.grid.shape == (3, 5)
    assert len(maze.tiles) == 1
    tile = maze.tiles[0]
    assert (tile.x, tile.y, tile.colors) == pytest.approx((3.75, 2.25, 1))
    assert tile.width == 1.5 and tile.length == DEFAULT_TILE_LENGTH
    assert tile.heading == pytest.approx(math.pi / 2)


def test_name_defaults_to_the_file_stem(tmp_path: Path):
    maze = read_maze_file(write(tmp_path, "corridor.maze", ">..\n"))
    assert maze.name == "corridor" and maze.source == str(tmp_path / "corridor.maze")


def test_tile_heading_follows_the_corridor():
    grid = np.array([list(row) for row in ["#.###", "#.#..", "...#.", "#.#..", "#####"]])
    assert grid_tile_heading(grid, 0, 1) == pytest.approx(math.pi / 2)  # dead end to the south
    assert grid_tile_heading(grid, 2, 1) == pytest.approx(math.pi / 2)  # plus crossing (tie)
    assert grid_tile_heading(grid, 2, 0) == 0.0  # east-west dead end
    assert grid_tile_heading(grid, 1, 4) == pytest.approx(math.pi / 2)  # corner W+S (tie)
    assert grid_tile_heading(grid, 1, 3) == 0.0  # corridor running east
    maze = parse_maze_text("#######\n.1.2.3.\n###.###\n", "m.maze")
    # '1' and '3' in an east-west corridor; '2' in a T whose bar runs east-west
    assert [t.heading for t in maze.tiles] == [0.0, 0.0, 0.0]
    assert [t.colors for t in maze.tiles] == [1, 2, 3]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "#.#\n#x#\n",
            "m.maze:2: unknown character 'x' in column 2 (expected one of # . 1 2 3 4 5 6 > < ^ v)",
        ),
        ("; c\ncell = abc\n.\n", "m.maze:2: cell must be a number of metres, got 'abc'"),
        ("cell = -1\n.\n", "m.maze:1: cell must be a finite number > 0"),
        ("cell = nan\n.\n", "m.maze:1: cell must be a finite number > 0"),
        ("colour = red\n.\n", "m.maze:1: unknown header key 'colour'"),
        ("cell = 1\ncell = 2\n.\n", "m.maze:2: header key 'cell' given twice"),
        ("= 3\n.\n", "m.maze:1: bad header line"),
        ("..\ncell = 2\n", "m.maze:2: header line after the grid has started"),
        ("..\n\n..\n", "m.maze:2: blank line inside the grid (grid lines follow on line 3)"),
        ("name = x\n###\n\n##\n", "m.maze:3: blank line inside the grid"),
        ("; only comments\n\n", "m.maze: no grid"),
        ("cell = 1\n###\n##\n", "m.maze:2: no free cell in the grid"),
        (" ..\n", "m.maze:1: unknown character ' ' in column 1"),
    ],
)
def test_maze_errors_name_file_and_line(text: str, message: str):
    with pytest.raises(MbnInputError) as info:
        parse_maze_text(text, "m.maze")
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_start_overlapping_a_wall_is_an_error_naming_its_line():
    # 0.5 m cells are narrower than the 0.4 x 0.511 m body with its offset origin
    with pytest.raises(
        MbnInputError,
        match=r"m\.maze:3: start #1 \('\^' in column 2\) at "
        r"\(0\.75, 0\.25, 90 deg\): the robot's body overlaps a wall",
    ):
        parse_maze_text("cell = 0.5\n...\n#^#\n", "m.maze")


def test_a_maze_without_a_corridor_is_refused_from_its_content_quickly():
    """A 1000 x 1000 checkerboard (no two free cells side by side: nowhere to drive) is refused
    in one line in well under a second, before its walls are merged or its starts checked; two
    free cells side by side are a corridor."""
    n = 1000
    rows = ["".join("." if (r + c) % 2 else "#" for c in range(n)) for r in range(n)]
    t0 = time.perf_counter()
    with pytest.raises(MbnInputError) as info:
        parse_maze_text("\n".join(["; a checkerboard", *rows]) + "\n", "m.maze")
    assert time.perf_counter() - t0 < 5.0
    assert str(info.value) == (
        "m.maze:2: no corridor: no two free cells side by side (each is walled in on four "
        "sides, e.g. a checkerboard); a maze needs free cells to drive between"
    )
    assert parse_maze_text("###\n#.#\n#.#\n###\n", "m.maze").grid.shape == (4, 3)
