"""The built-in mazes: crossroads, the Stage arena, fig4, heldout, validation and the mazes with
three kinds of tile."""

from __future__ import annotations

import math

import jax
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.world.geometry import collides as eager_collides
from mbn.world.junctions import decision_cells, free_neighbours, rule_exit
from mbn.world.mazes.builtin import (
    BUILTIN_NAMES,
    CROSSROAD_KINDS,
    builtin_maze,
    crossroad,
    crossroad_text,
    describe_builtins,
)
from mbn.world.mazes.load import load_maze
from mbn.world.mazes.model import Maze

collides = jax.jit(eager_collides)

# the README's walls table (wall00..wall09)
README_WALLS = [
    (0.0, 14.0, 0.0, 1.0),
    (0.0, 4.0, 1.0, 4.6),
    (5.2, 11.8, 1.0, 4.6),
    (13.0, 14.0, 1.0, 10.4),
    (0.0, 1.0, 4.6, 10.4),
    (1.0, 4.0, 5.8, 10.4),
    (5.2, 9.4, 5.8, 10.4),
    (10.6, 13.0, 5.8, 8.2),
    (4.0, 5.2, 9.4, 10.4),
    (9.4, 13.0, 9.4, 10.4),
]


def test_names_and_descriptions():
    assert BUILTIN_NAMES == (
        "cross_L",
        "cross_S",
        "cross_R",
        "cross_LS",
        "cross_LR",
        "cross_SR",
        "cross_LSR",
        "stage_arena",
        "fig4",
        "heldout",
        "validation",
        "validation2",
        "tiles3",
        "tiles3_heldout",
        "tiles3_validation",
        "zs_long",
        "zs_dense",
        "zs_hall",
        "zs_spiral",
        "zs_comb",
        "zs_stairs",
        "zs_far_tiles2",
        "zs_dense_tiles2",
        "zs_far_tiles3",
    )
    described = describe_builtins()
    assert [name for name, _ in described] == list(BUILTIN_NAMES)
    assert all(text and "\n" not in text for _, text in described)
    with pytest.raises(MbnInputError, match="unknown built-in maze 'nope' \\(known: cross_L, "):
        builtin_maze("nope")


# exits of each kind, as compass directions from the junction (entered moving north)
OPEN = {"L": "W", "S": "N", "R": "E"}


@pytest.mark.parametrize("kind", CROSSROAD_KINDS)
def test_crossroads_have_exactly_their_exits(kind: str):
    maze = builtin_maze(f"cross_{kind}")
    assert maze.name == f"cross_{kind}" and maze.source == "builtin"
    assert maze.grid is not None and maze.grid.shape == (7, 7) and maze.cell == 1.2
    junction = (3, 3)
    nb = free_neighbours(maze)[junction]
    want = {"S"} | {OPEN[k] for k in kind}
    assert {h for h, is_open in zip("NESW", nb, strict=True) if is_open} == want
    # every free cell is the junction or on an arm of 3 cells; each arm ends closed
    assert int((maze.grid != "#").sum()) == 1 + 3 * (1 + len(kind))
    decision = decision_cells(maze)
    if kind == "S":
        assert not decision.any()
    else:
        assert np.argwhere(decision).tolist() == [[3, 3]]
        right = next(e for e, k in (("right", "R"), ("straight", "S"), ("left", "L")) if k in kind)
        left = next(e for e, k in (("left", "L"), ("straight", "S"), ("right", "R")) if k in kind)
        assert rule_exit(maze, junction, "N", "right") == right
        assert rule_exit(maze, junction, "N", "left") == left
    # one start at the south end cell's centre, facing north
    np.testing.assert_allclose(maze.starts, [[4.2, 0.6, math.pi / 2]])
    assert maze.bounds == pytest.approx((0.0, 8.4, 0.0, 8.4)) and maze.outside_is_wall
    assert maze.tiles == ()


@pytest.mark.parametrize("approach", ["west", "east"])
def test_crossroads_entered_round_a_corner(approach: str):
    maze = crossroad("LS", approach=approach)
    assert maze.name == f"cross_LS_from_{approach}"
    heading = {"west": 0.0, "east": math.pi}[approach]
    x = {"west": 0.6, "east": 7.8}[approach]
    np.testing.assert_allclose(maze.starts, [[x, 0.6, heading]])
    # the south corridor leads from the start to the south arm's end cell, then north
    for c in range(7):
        on_corridor = c <= 3 if approach == "west" else c >= 3
        assert maze.is_free(0.6 + 1.2 * c, 0.6) == on_corridor
    # the junction and its exits are those of the plain crossroad
    plain = crossroad("LS")
    assert free_neighbours(maze)[(3, 3)].tolist() == free_neighbours(plain)[(3, 3)].tolist()
    assert rule_exit(maze, (3, 3), "N", "left") == "left"
    # the corner is turned away from the approach: left from the west, right from the east
    text = crossroad_text("LS", approach=approach)
    assert text.splitlines()[-1] == (">...###" if approach == "west" else "###...<")
    with pytest.raises(MbnInputError, match="tile needs the approach"):
        crossroad("LS", approach=approach, tile=1)
    with pytest.raises(MbnInputError, match="approach must be"):
        crossroad("LS", approach="north")


def test_crossroads_entered_from_one_cell_short_of_the_junction():
    maze = crossroad("LSR", approach="near")
    assert maze.name == "cross_LSR_near"
    # the start is the centre of the cell next to the junction (3, 3), facing north
    np.testing.assert_allclose(maze.starts, [[4.2, 3.0, math.pi / 2]])
    plain = crossroad("LSR")
    assert free_neighbours(maze)[(3, 3)].tolist() == free_neighbours(plain)[(3, 3)].tolist()
    # the south arm behind the start is still open: only the start mark moved
    for r in range(3):
        assert maze.is_free(4.2, 0.6 + 1.2 * r)
    with pytest.raises(MbnInputError, match="tile needs the approach"):
        crossroad("LSR", approach="near", tile=2)


def test_cross_lr_rules_and_arm_lengths():
    maze = crossroad("cross_LR")
    assert rule_exit(maze, (3, 3), "N", "right") == "right"
    assert rule_exit(maze, (3, 3), "N", "left") == "left"
    # the east arm is 3 cells = 3.6 m from the junction's east edge (x = 4.8) to x = 8.4
    assert maze.is_free(8.3, 4.2) and not maze.is_free(8.5, 4.2)
    assert not maze.is_free(4.2, 5.0)  # no north exit
    assert crossroad_text("LR") == "#######\n#######\n#######\n.......\n###.###\n###.###\n###^###\n"


def test_crossroad_options():
    maze = crossroad("SR", arm_cells=5, cell=1.5, tile=2)
    assert maze.name == "cross_SR_tile2" and maze.grid is not None
    assert maze.grid.shape == (11, 11) and maze.cell == 1.5
    np.testing.assert_allclose(maze.starts, [[8.25, 0.75, math.pi / 2]])
    (tile,) = maze.tiles
    assert (tile.x, tile.y, tile.colors, tile.width) == pytest.approx((8.25, 2.25, 2, 1.5))
    assert tile.heading == pytest.approx(math.pi / 2)
    assert crossroad("L", tile=1).tiles[0].colors == 1
    assert crossroad("LSR", tile=3).tiles[0].colors == 3  # the three-behaviour task's
    for bad, message in [
        (dict(kind="X"), "unknown crossroad kind 'X'"),
        (dict(kind="RL"), "unknown crossroad kind 'RL'"),
        (dict(kind="L", tile=7), r"tile must be one of 1, 2, 3, 4, 5, 6 or None, got 7"),
        (dict(kind="L", arm_cells=0), "arm_cells must be an integer >= 1"),
        (dict(kind="L", arm_cells=1, tile=1), "a tile needs arm_cells >= 2"),
        (dict(kind="L", cell=-1.0), "cell must be a finite number > 0"),
    ]:
        with pytest.raises(MbnInputError, match=message):
            crossroad(**bad)  # type: ignore[arg-type]


def test_stage_arena_is_the_readme_table():
    maze = builtin_maze("stage_arena")
    np.testing.assert_array_equal(maze.walls, np.array(README_WALLS))
    assert maze.bounds == (0.0, 14.0, 0.0, 10.4) and maze.grid is None
    # corridor centres and junction centres are free; wall interiors are not
    for x, y in [(7.0, 5.2), (4.6, 2.0), (10.0, 7.0), (12.0, 8.8), (12.4, 3.0), (4.6, 5.2)]:
        assert maze.is_free(x, y)
    for x, y in [(2.0, 2.0), (7.0, 8.0), (13.5, 5.0), (11.8, 7.0)]:
        assert not maze.is_free(x, y)
    assert len(maze.starts) >= 4
    assert not np.asarray(collides(maze.starts, maze.solid_rects())).any()


# ------------------------------------------------------------------------------------------
# fig4 and heldout: a tiny cell-walking simulation of the wall-following rules

STEP = {0: (-1, 0), 1: (0, 1), 2: (1, 0), 3: (0, -1)}  # N E S W as (d_row, d_col)
TURN = {"straight": 0, "right": 1, "back": 2, "left": 3}
MARK_HEADING = {"^": 0, ">": 1, "v": 2, "<": 3}


def walk_cells(maze: Maze, row: int, col: int, heading: int, rule: str, moves: int) -> list:
    """The cells a rule-following walker enters, in order."""
    assert maze.grid is not None
    cells = []
    for _ in range(moves):
        exit_ = rule_exit(maze, (row, col), "NESW"[heading], rule)  # type: ignore[arg-type]
        heading = (heading + TURN[exit_]) % 4
        dr, dc = STEP[heading]
        row, col = row + dr, col + dc
        assert maze.grid[row, col] != "#"
        cells.append((row, col))
    return cells


def walk(maze: Maze, row: int, col: int, heading: int, rule: str, moves: int) -> list:
    """Cells with >= 3 free neighbours that a rule-following walker enters, in order."""
    nb = free_neighbours(maze)
    return [
        (r, c) for r, c in walk_cells(maze, row, col, heading, rule, moves) if nb[r, c].sum() >= 3
    ]


@pytest.mark.parametrize(
    ("name", "min_starts"), [("fig4", 10), ("heldout", 10), ("validation", 8), ("validation2", 8)]
)
def test_test_mazes(name: str, min_starts: int):
    maze = load_maze(name)
    assert maze.name == name and maze.grid is not None and maze.cell == 1.2
    assert len(maze.starts) >= min_starts
    assert {t.colors for t in maze.tiles} == {1, 2}
    assert not np.asarray(collides(maze.starts, maze.solid_rects())).any()
    nb = free_neighbours(maze)
    count = nb.sum(-1) * (maze.grid != "#")
    kinds = {
        "plus": int((count == 4).sum()),
        "T": int((count == 3).sum()),
        "L": int(decision_cells(maze).sum() - (count >= 3).sum()),
    }
    assert kinds["plus"] >= 1 and kinds["T"] >= 3 and kinds["L"] >= 2, kinds
    # starts lie mid-corridor facing along it: open ahead and behind, walls on both sides
    marks = [
        (r, c) for r, c in zip(*np.nonzero(np.isin(maze.grid, list(MARK_HEADING))), strict=True)
    ]
    assert len(marks) == len(maze.starts)
    for r, c in marks:
        h = MARK_HEADING[str(maze.grid[r, c])]
        assert nb[r, c, h] and nb[r, c, (h + 2) % 4]
        assert not nb[r, c, (h + 1) % 4] and not nb[r, c, (h + 3) % 4]
        for rule in ("right", "left"):
            crossings = walk(maze, int(r), int(c), h, rule, moves=30)
            assert len(crossings) >= 3 and len(set(crossings[:6])) >= 3, (name, r, c, rule)
    # tiles lie in corridor cells (not on starts or walls) across the corridor
    for tile in maze.tiles:
        assert maze.is_free(tile.x, tile.y) and tile.width == 1.2


@pytest.mark.parametrize("name", ["validation", "validation2"])
def test_the_validation_mazes_serve_the_straight_rules_too(name: str):
    # `mbn run new-behaviours` validates its straight-right and straight-left programs there
    maze = load_maze(name)
    assert maze.grid is not None
    for r, c in zip(*np.nonzero(np.isin(maze.grid, list(MARK_HEADING))), strict=True):
        h = MARK_HEADING[str(maze.grid[r, c])]
        for rule in ("straight-right", "straight-left"):
            crossings = walk(maze, int(r), int(c), h, rule, moves=30)
            assert len(crossings) >= 3 and len(set(crossings[:6])) >= 3, (name, r, c, rule)


@pytest.mark.parametrize("name", ["fig4", "heldout", "validation", "validation2"])
def test_every_wall_following_circuit_of_the_test_mazes_meets_a_tile(name: str):
    # The MBN is judged from the first tile it drives over: a start from which a wall follower
    # circles without ever meeting a tile would test nothing (docs/mazes.md).
    maze = load_maze(name)
    assert maze.grid is not None
    nb = free_neighbours(maze)
    for r, c in zip(*np.nonzero(np.isin(maze.grid, list(MARK_HEADING))), strict=True):
        h = MARK_HEADING[str(maze.grid[r, c])]
        for rule in ("right", "left"):
            cells = walk_cells(maze, int(r), int(c), h, rule, moves=80)
            first = next((k for k, (a, b) in enumerate(cells) if maze.grid[a, b] in "12"), None)
            assert first is not None, (name, int(r), int(c), rule)
            after = [cell for cell in cells[first:] if nb[cell].sum() >= 3]
            assert len(after) >= 3, (name, int(r), int(c), rule)


@pytest.mark.parametrize(
    ("one", "other"),
    [
        (a, b)
        for i, a in enumerate(("fig4", "heldout", "validation", "validation2"))
        for b in ("fig4", "heldout", "validation", "validation2")[i + 1 :]
    ],
)
def test_the_test_and_validation_mazes_differ(one, other):
    a, b = builtin_maze(one), builtin_maze(other)
    assert a.grid is not None and b.grid is not None
    assert a.grid.shape != b.grid.shape or (a.grid != b.grid).any()


@pytest.mark.parametrize("name", ["tiles3", "tiles3_heldout", "tiles3_validation"])
def test_the_three_tile_mazes(name: str):
    """Tiles of all three kinds (at least three each), plus, T and L junctions, no dead end, ten
    or more start marks mid-corridor; from every mark each of the rules right, left,
    straight-right and straight-left passes three junctions, and with tiles putting right, left
    and straight-right in force a robot starting as either wall follower drives over a tile and
    then through three junctions (rule_route walks the grid cell by cell). And the test judges
    the programs: with either first rule, a controller that follows another tile's rule after a
    tile of one kind (one program swapped for another) takes a wrong exit among the three
    junctions judged from at least four of the marks (program_swaps_caught): more than a third
    of them, each with its jittered starts. The first tiles3 failed this: straight-right and
    right took the same exit at every junction judged after a three-colour tile, and an MBN with
    the right-hand rule's program for three colours passed every trial."""
    from mbn.world.junctions import program_swaps_caught, rule_route

    maze = load_maze(name)
    assert maze.name == name and maze.grid is not None and maze.cell == 1.2
    kinds = [t.colors for t in maze.tiles]
    assert all(kinds.count(k) >= 3 for k in (1, 2, 3)), kinds
    assert len(maze.starts) >= 10
    nb = free_neighbours(maze)
    count = nb.sum(-1) * (maze.grid != "#")
    assert int((count == 4).sum()) >= 2 and int((count == 3).sum()) >= 3
    assert int(decision_cells(maze).sum() - (count >= 3).sum()) >= 2  # L corners
    assert int((count == 1).sum()) == 0  # no dead end
    for r, c in zip(*np.nonzero(np.isin(maze.grid, list(MARK_HEADING))), strict=True):
        h = MARK_HEADING[str(maze.grid[r, c])]
        assert nb[r, c, h] and nb[r, c, (h + 2) % 4]
        assert not nb[r, c, (h + 1) % 4] and not nb[r, c, (h + 3) % 4]
    rules = ("right", "left", "straight-right")
    for start in maze.starts:
        for rule in ("right", "left", "straight-right", "straight-left"):
            assert rule_route(maze, tuple(start), rule, 3) is not None, (name, start, rule)
        for first in ("right", "left"):
            route = rule_route(
                maze,
                tuple(start),
                first,
                3,
                follow_tiles=True,
                count_from_tile=True,
                tile_rules=rules,
            )
            assert route is not None, (name, start, first)
    with pytest.raises(MbnInputError, match="3-colour tile"):
        rule_route(maze, tuple(maze.starts[0]), "right", 3, follow_tiles=True)
    for first in ("right", "left"):
        counts = program_swaps_caught(maze, first, 3, rules)
        assert len(counts) == 6
        for (kind, other), caught in counts.items():
            assert caught >= 4, (name, first, kind, other, caught)


def test_the_three_tile_mazes_differ_from_each_other_and_the_others():
    names = ("tiles3", "tiles3_heldout", "tiles3_validation")
    others = ("fig4", "heldout", "validation", "validation2")
    for i, name in enumerate(names):
        a = builtin_maze(name).grid
        assert a is not None
        for other in (*names[i + 1 :], *others):
            g = builtin_maze(other).grid
            assert g is not None and (g.shape != a.shape or (g != a).any()), (name, other)
