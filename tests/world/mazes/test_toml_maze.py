"""The TOML maze reader."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbn.errors import MbnInputError
from mbn.world.mazes.toml_maze import parse_toml_maze

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
            "b.toml:1: [[wall]] #1: xmin: expected a finite number, got '0'",
        ),
        (
            "[[wall]]\nxmin = true\nxmax = 1\nymin = 0\nymax = 1\n",
            "xmin: expected a finite number, got True",
        ),
        (
            "[[wall]]\nxmin = nan\nxmax = 1\nymin = 0\nymax = 1\n",
            "xmin: expected a finite number, got nan",
        ),
        (
            rects_toml("wall", [(0, 1, 0, 1)]) + "[[tile]]\nx = 2\ny = 2\ncolors = 7\n",
            "b.toml:6: [[tile]] #1: colors must be an integer from 1 to 6, got 7",
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
