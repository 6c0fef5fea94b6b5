"""The .maze and TOML readers, validation and the loader."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbn.errors import MbnInputError
from mbn.world.mazes.builtin import BUILTIN_NAMES
from mbn.world.mazes.load import (
    grid_tile_heading,
    load_maze,
    parse_maze_text,
    parse_toml_maze,
    read_maze_file,
    validate_maze,
)
from mbn.world.mazes.model import DEFAULT_TILE_LENGTH, Maze, merge_cells, merge_grid


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# --------------------------------------------------------------------------------------------
# .maze grids


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
    maze = parse_maze_text("#####\n.1.2.\n###.#\n", "m.maze")
    # '1' in an east-west corridor; '2' in a T whose bar runs east-west
    assert [t.heading for t in maze.tiles] == [0.0, 0.0]
    assert [t.colors for t in maze.tiles] == [1, 2]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "#.#\n#x#\n",
            "m.maze:2: unknown character 'x' in column 2 (expected one of # . 1 2 > < ^ v)",
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


# --------------------------------------------------------------------------------------------
# TOML mazes

WALLS_ONLY = """
name = "posts"

[[wall]]
xmin = 0.0
xmax = 1.0
ymin = 0.0
ymax = 1.0

[[wall]]
xmin = 3.0
xmax = 4.0
ymin = 2.0
ymax = 5.0

[[tile]]
x = 2.0
y = 2.0
colors = 2
heading = 0

[[start]]
x = 2.0
y = 0.5
theta = 90
"""


def test_toml_walls_only():
    maze = parse_toml_maze(WALLS_ONLY, "w.toml")
    assert maze.name == "posts" and not maze.outside_is_wall and maze.grid is None
    np.testing.assert_allclose(maze.walls, [[0, 1, 0, 1], [3, 4, 2, 5]])
    assert maze.bounds == (0.0, 4.0, 0.0, 5.0)
    np.testing.assert_allclose(maze.starts, [[2.0, 0.5, math.pi / 2]])
    (tile,) = maze.tiles
    assert (tile.x, tile.y, tile.colors, tile.heading) == (2.0, 2.0, 2, 0.0)
    assert (tile.width, tile.length) == (1.2, 0.3)


def test_toml_bounds_grow_to_hold_starts_outside_the_walls():
    text = "[[wall]]\nxmin = 0\nxmax = 1\nymin = 0\nymax = 1\n[[start]]\nx = 3\ny = -2\ntheta = 0\n"
    maze = parse_toml_maze(text, "w.toml")
    assert maze.bounds == (0.0, 3.0, -2.0, 1.0)


def rects_toml(table: str, rects: list[tuple[float, float, float, float]]) -> str:
    return "".join(
        f"[[{table}]]\nxmin = {a}\nxmax = {b}\nymin = {c}\nymax = {d}\n" for a, b, c, d in rects
    )


def test_toml_free_rectangles_give_their_exact_complement():
    # an L: a corridor east and one north from its east end
    maze = parse_toml_maze(rects_toml("free", [(0, 3, 0, 1), (2, 3, 0, 3)]), "l.toml")
    assert maze.outside_is_wall and maze.bounds == (0.0, 3.0, 0.0, 3.0)
    np.testing.assert_allclose(maze.walls, [[0, 2, 1, 3]])
    # a plus: the four corners are solid
    plus = parse_toml_maze(rects_toml("free", [(0, 3, 1, 2), (1, 2, 0, 3)]), "p.toml")
    got = sorted(map(tuple, plus.walls.tolist()))
    assert got == [(0, 1, 0, 1), (0, 1, 2, 3), (2, 3, 0, 1), (2, 3, 2, 3)]


def test_toml_free_and_wall_tables_combine():
    text = rects_toml("free", [(0, 4, 0, 2)]) + rects_toml("wall", [(1.5, 2.5, 0.5, 1.5)])
    maze = parse_toml_maze(text, "c.toml")
    np.testing.assert_allclose(maze.walls, [[1.5, 2.5, 0.5, 1.5]])
    assert maze.outside_is_wall and not maze.is_free(2.0, 1.0) and maze.is_free(0.5, 1.0)


@settings(max_examples=25, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(0, 5), st.integers(1, 4), st.integers(0, 5), st.integers(1, 4)),
        min_size=1,
        max_size=4,
    )
)
def test_toml_free_complement_matches_the_union(boxes: list[tuple[int, int, int, int]]):
    free = [(x, x + w, y, y + h) for x, w, y, h in boxes]
    maze = parse_toml_maze(rects_toml("free", free), "h.toml")
    x0, x1, y0, y1 = maze.bounds
    for px in np.arange(x0 + 0.25, x1, 0.5):
        for py in np.arange(y0 + 0.25, y1, 0.5):
            inside = any(a < px < b and c < py < d for a, b, c, d in free)
            assert maze.is_free(px, py) == inside
    # the solid rectangles do not overlap each other
    w = maze.walls
    for i in range(len(w)):
        for j in range(i + 1, len(w)):
            assert min(w[i, 1], w[j, 1]) <= max(w[i, 0], w[j, 0]) or min(w[i, 3], w[j, 3]) <= max(
                w[i, 2], w[j, 2]
            )


def test_toml_syntax_errors_name_the_line():
    with pytest.raises(MbnInputError) as info:
        parse_toml_maze("name = 'x'\n[[wall]]\nxmin = 1.0.0\n", "s.toml")
    msg = str(info.value)
    assert msg.startswith("s.toml:3: TOML syntax error: ") and "(column" in msg
    assert "\n" not in msg
    with pytest.raises(MbnInputError, match=r"^s\.toml:2: TOML syntax error: .*end of file"):
        parse_toml_maze("[[wall]]\nxmin = ", "s.toml")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            rects_toml("wall", [(0, 1, 0, 1), (2, 2, 0, 1)]),
            "b.toml:6: [[wall]] #2: xmin must be < xmax, got 2, 2",
        ),
        (rects_toml("free", [(0, 1, 1, 0)]), "b.toml:1: [[free]] #1: ymin must be < ymax"),
        ("[[wall]]\nxmin = 0\nxmax = 1\nymin = 0\n", "b.toml:1: [[wall]] #1: missing ymax"),
        (
            "[[wall]]\nxmin = 0\nxmax = 1\nymin = 0\nymax = 1\nzmax = 2\n",
            "[[wall]] #1: unknown key 'zmax'",
        ),
        (
            "[[wall]]\nxmin = '0'\nxmax = 1\nymin = 0\nymax = 1\n",
            "b.toml:1: [[wall]] #1: xmin must be a number, got '0'",
        ),
        (
            "[[wall]]\nxmin = true\nxmax = 1\nymin = 0\nymax = 1\n",
            "xmin must be a number, got True",
        ),
        ("[[wall]]\nxmin = nan\nxmax = 1\nymin = 0\nymax = 1\n", "xmin must be finite"),
        (
            rects_toml("wall", [(0, 1, 0, 1)]) + "[[tile]]\nx = 2\ny = 2\ncolors = 3\n",
            "b.toml:6: [[tile]] #1: colors must be 1 or 2, got 3",
        ),
        (
            rects_toml("wall", [(0, 1, 0, 1)]) + "[[tile]]\nx = 2\ny = 2\ncolors = 1\nwidth = 0\n",
            "[[tile]] #1: width and length must be > 0",
        ),
        (
            rects_toml("wall", [(0, 1, 0, 1)]) + "[[start]]\nx = 3\ny = 3\n",
            "b.toml:6: [[start]] #1: missing theta",
        ),
        ("wall = 3\n", "b.toml: wall must be an array of tables ([[wall]])"),
        ("walls = []\n", "b.toml: unknown top-level key 'walls'"),
        (
            "name = 3\n" + rects_toml("wall", [(0, 1, 0, 1)]),
            "b.toml: name must be a non-empty string",
        ),
        ("name = 'x'\n", "b.toml: a TOML maze needs at least one [[wall]] or [[free]] table"),
        (
            "wall = [{xmin = 0, xmax = 0, ymin = 0, ymax = 1}]\n",
            "b.toml: [[wall]] #1: xmin must be < xmax",
        ),
    ],
)
def test_toml_value_errors_name_table_index_and_line(text: str, message: str):
    with pytest.raises(MbnInputError) as info:
        parse_toml_maze(text, "b.toml")
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_toml_start_in_a_wall_and_tile_off_free_space():
    free = rects_toml("free", [(0, 4, 0, 1.2)])
    with pytest.raises(
        MbnInputError,
        match=r"^t\.toml:6: \[\[start\]\] #1 at \(0\.1, 0\.6, 0 "
        r"deg\): the robot's body overlaps a wall$",
    ):
        parse_toml_maze(free + "[[start]]\nx = 0.1\ny = 0.6\ntheta = 0\n", "t.toml")
    with pytest.raises(
        MbnInputError,
        match=r"^t\.toml:6: \[\[tile\]\] #1 at \(2, 3\): its "
        r"centre is not in free space$",
    ):
        parse_toml_maze(free + "[[tile]]\nx = 2\ny = 3\ncolors = 1\n", "t.toml")
    with pytest.raises(MbnInputError, match=r"\[\[start\]\] #1 at \(9, 0\.6, 0 deg\) lies outside"):
        parse_toml_maze(free + "[[start]]\nx = 9\ny = 0.6\ntheta = 0\n", "t.toml")


# --------------------------------------------------------------------------------------------
# validation and loading


def test_validate_maze_rejects_a_maze_without_free_space():
    full = Maze(name="full", walls=[[0, 1, 0, 2], [1, 2, 0, 2]], bounds=(0, 2, 0, 2))
    with pytest.raises(MbnInputError, match=r"^full: the maze has no free space$"):
        validate_maze(full, "full")
    open_outside = Maze(name="o", walls=[[0, 2, 0, 2]], bounds=(0, 2, 0, 2), outside_is_wall=False)
    validate_maze(open_outside, "o")  # the outside is free


def test_merge_cells_with_rectangular_cells_and_an_origin():
    solid = np.array([[True, False], [True, True]])
    np.testing.assert_allclose(
        merge_cells(solid, 2.0, 0.5, origin=(1.0, -1.0)),
        [[1.0, 3.0, -0.5, 0.0], [1.0, 5.0, -1.0, -0.5]],
    )
    np.testing.assert_allclose(merge_cells(solid, 1.0), [[0, 1, 1, 2], [0, 2, 0, 1]])
    with pytest.raises(MbnInputError, match="needs 3 x edges"):
        merge_grid(solid, np.arange(4.0), np.arange(3.0))


def test_load_maze_dispatches_on_name_and_suffix(tmp_path: Path):
    assert load_maze("cross_LR").name == "cross_LR"
    grid = load_maze(write(tmp_path, "g.maze", ">.\n"))
    assert grid.name == "g" and grid.grid is not None
    toml = load_maze(str(write(tmp_path, "w.toml", WALLS_ONLY)))
    assert toml.name == "posts"


def test_load_maze_errors(tmp_path: Path):
    with pytest.raises(MbnInputError) as info:
        load_maze("no_such_maze")
    msg = str(info.value)
    assert msg.startswith("unknown maze 'no_such_maze': neither a built-in (")
    for name in BUILTIN_NAMES:
        assert name in msg
    with pytest.raises(MbnInputError, match=r"missing\.maze: no such file$"):
        load_maze(tmp_path / "missing.maze")
    with pytest.raises(MbnInputError, match=r"cannot tell the maze format from the suffix '\.txt'"):
        load_maze(write(tmp_path, "m.txt", ">.\n"))
    folder = tmp_path / "d.maze"
    folder.mkdir()
    with pytest.raises(MbnInputError, match="is a folder"):
        load_maze(folder)
    bad = tmp_path / "b.maze"
    bad.write_bytes(b"\xff\xfe.\n")
    with pytest.raises(MbnInputError, match=r"b\.maze: not UTF-8 text"):
        load_maze(bad)
