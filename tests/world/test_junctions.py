"""Junction analysis: decision cells, rule exits, per-cell tables, and passes of a trajectory."""

from __future__ import annotations

import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.world.junctions import (
    EXIT_CODES,
    HEADINGS,
    JunctionPass,
    RoutePass,
    cell_of,
    decision_cells,
    junction_sequence,
    junction_tables,
    route_passes,
    rule_exit,
    rule_route,
)
from mbn.world.mazes.builtin import crossroad, stage_arena
from mbn.world.mazes.grid_text import parse_maze_text

# a plus at (1, 2), a T at (3, 2) (exits W, E, N), corners at (1, 0), (1, 4), (3, 0), dead ends
# at (0, 2), (2, 4), (3, 3)
SMALL = parse_maze_text(
    "\n".join(
        [
            "##.##",  # 0
            "..>..",  # 1: the plus is (1, 2)
            ".#.#.",  # 2
            "..^.#",  # 3: the T is (3, 2)
            "#####",  # 4
        ]
    ),
    "small.maze",
)


def test_decision_cells_of_a_small_maze():
    want = np.zeros((5, 5), dtype=bool)
    want[1, 2] = True  # plus: N, S, E, W
    want[1, 0] = True  # corner: E and S
    want[1, 4] = True  # corner: W and S
    want[3, 0] = True  # corner: N and E
    want[3, 2] = True  # T: N, W, E
    # (3, 3): W only -> dead end; (2, 4): N only -> dead end; (0, 2): S only -> dead end
    np.testing.assert_array_equal(decision_cells(SMALL), want)


def test_rule_exits_at_a_plus_a_t_a_corner_and_a_dead_end():
    assert rule_exit(SMALL, (1, 2), "N", "right") == "right"
    assert rule_exit(SMALL, (1, 2), "N", "left") == "left"
    # the T at (3, 2) entered from the north (moving S): W is right, E is left, S is closed
    assert rule_exit(SMALL, (3, 2), "S", "right") == "right"
    assert rule_exit(SMALL, (3, 2), "S", "left") == "left"
    # entered moving east (from the west): right (S) closed, straight (E) open
    assert rule_exit(SMALL, (3, 2), "E", "right") == "straight"
    assert rule_exit(SMALL, (3, 2), "E", "left") == "left"
    # corner (1, 0) with exits E and S, entered moving north: right = E
    assert rule_exit(SMALL, (1, 0), "N", "right") == "right"
    assert rule_exit(SMALL, (1, 0), "N", "left") == "right"
    assert rule_exit(SMALL, (1, 0), "W", "left") == "left"  # moving west, left is south
    # dead end (0, 2) entered moving north
    assert rule_exit(SMALL, (0, 2), "N", "right") == "back"
    assert rule_exit(SMALL, (0, 2), "N", "left") == "back"


def test_rule_exit_errors():
    with pytest.raises(MbnInputError, match=r"cell \(0, 0\) of 'small' is a wall"):
        rule_exit(SMALL, (0, 0), "N", "right")
    with pytest.raises(MbnInputError, match="outside the 5 x 5 grid"):
        rule_exit(SMALL, (5, 0), "N", "right")
    with pytest.raises(MbnInputError, match="heading must be one of N E S W, got 'up'"):
        rule_exit(SMALL, (1, 2), "up", "right")
    with pytest.raises(MbnInputError, match="unknown rule 'both'"):
        rule_exit(SMALL, (1, 2), "N", "both")  # type: ignore[arg-type]
    with pytest.raises(MbnInputError, match="junction analysis needs a grid maze"):
        decision_cells(stage_arena())
    with pytest.raises(MbnInputError, match="junction analysis needs a grid maze"):
        junction_sequence(stage_arena(), np.zeros((3, 3)))


def test_junction_tables_match_rule_exit():
    tables = junction_tables(SMALL)
    assert tables["right"].shape == (5, 5, 4) and tables["right"].dtype == np.int8
    assert tables["left"].dtype == np.int8
    decision = decision_cells(SMALL)
    np.testing.assert_array_equal(tables["decision"], decision)
    for r in range(5):
        for c in range(5):
            for h, heading in enumerate(HEADINGS):
                for rule in ("right", "left"):
                    got = int(tables[rule][r, c, h])
                    if decision[r, c]:
                        assert got == EXIT_CODES[rule_exit(SMALL, (r, c), heading, rule)]
                    else:
                        assert got == -1
    # the plus entered moving north: right rule 1 (right), left rule 3 (left)
    assert tables["right"][1, 2, 0] == 1 and tables["left"][1, 2, 0] == 3
    assert EXIT_CODES == {"back": 0, "right": 1, "straight": 2, "left": 3}
    np.testing.assert_array_equal(tables["open"][1, 2], [True, True, True, True])
    np.testing.assert_array_equal(tables["open"][0, 2], [False, False, True, False])


def test_cell_of():
    # 5 x 5 cells of 1.2 m: row 0 is y in [4.8, 6.0]
    assert cell_of(SMALL, 0.1, 5.9) == (0, 0)
    assert cell_of(SMALL, 1.2, 1.2) == (3, 1)  # on a border: the cell east / north
    assert cell_of(SMALL, 5.99, 0.01) == (4, 4)
    assert cell_of(SMALL, -3.0, 99.0) == (0, 0)  # outside: the nearest cell


def straight(a: tuple[float, float], b: tuple[float, float], step: float = 0.1) -> np.ndarray:
    n = max(1, round(np.hypot(b[0] - a[0], b[1] - a[1]) / step))
    t = np.arange(n) / n
    return np.stack([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), np.zeros(n)], -1)


def test_a_right_turn_through_a_t():
    maze = crossroad("LR")  # 7 x 7 cells of 1.2 m; junction (3, 3), centre (4.2, 4.2)
    path = np.concatenate(
        [straight((4.2, 0.65), (4.2, 4.25)), straight((4.25, 4.2), (7.85, 4.2)), [[7.85, 4.2, 0]]]
    )
    (p,) = junction_sequence(maze, path)
    assert p == JunctionPass(
        cell=(3, 3),
        entered_heading="N",
        exit="right",
        right_rule_exit="right",
        left_rule_exit="left",
        step_in=30,  # y = 3.6 is the junction's south border: 0.65 + 30 * 0.1
        step_out=36 + 6,  # x = 4.8 is its east border: 4.25 + 6 * 0.1
    )
    assert path[p.step_in, 1] == pytest.approx(3.65)
    assert path[p.step_out, 0] == pytest.approx(4.85)


def test_wobbling_across_a_border_and_open_passes():
    maze = crossroad("LSR")
    # drive north into the junction, wobble back across its south border, then go straight on
    ys = [3.3, 3.5, 3.65, 3.55, 3.65, 4.2, 4.95, 5.0]
    poses = np.array([[4.2, y, np.pi / 2] for y in ys])
    passes = junction_sequence(maze, poses)
    assert [(p.exit, p.step_in, p.step_out) for p in passes] == [
        ("back", 2, 3),
        ("straight", 4, 6),
    ]
    # with hysteresis the wobble (5 cm into the cell) does not count as entering it
    (once,) = junction_sequence(maze, poses, margin=0.1)
    assert (once.exit, once.step_in, once.step_out) == ("straight", 5, 6)
    # a pass still open at the end, and a trajectory starting inside the junction: not reported
    assert junction_sequence(maze, poses[:5]) == passes[:1]
    assert junction_sequence(maze, poses[5:]) == []
    with pytest.raises(MbnInputError, match="margin must be >= 0"):
        junction_sequence(maze, poses, margin=-1.0)
    with pytest.raises(MbnInputError, match=r"poses must be \(T, 3\)"):
        junction_sequence(maze, np.zeros(3))


def test_cross_s_has_no_decision_cell_and_passes_nothing():
    maze = crossroad("S")
    assert not decision_cells(maze).any()
    assert junction_sequence(maze, straight((4.2, 0.6), (4.2, 7.8))) == []


def test_route_passes_name_the_rule_in_force_where_it_came_from_and_the_exits_open():
    """Two crossings in a row: a three-colour tile before the first puts straight-right in force
    (source 3) and the walk goes straight on; before the second a one-colour tile puts right in
    force (source 1). Without tiles followed, the rule the walk starts with (source 0) holds."""
    maze = parse_maze_text(
        "name = two\ncell = 1.2\n"
        "#######\n"
        "#.....#\n"
        "###.###\n"
        "###1###\n"
        "#.....#\n"
        "###.###\n"
        "###3###\n"
        "###^###\n"
        "#######\n"
    )
    tiles = ("right", "left", "straight-right")
    start = tuple(maze.starts[0])
    assert route_passes(maze, start, "left", 2, follow_tiles=True, tile_rules=tiles) == [
        RoutePass("straight-right", 3, frozenset({"right", "straight", "left", "back"})),
        RoutePass("right", 1, frozenset({"right", "left", "back"})),
    ]
    assert route_passes(maze, start, "left", 1) == [
        RoutePass("left", 0, frozenset({"right", "straight", "left", "back"}))
    ]
    # the route it walks is rule_route's
    length = rule_route(maze, start, "left", 2, follow_tiles=True, tile_rules=tiles)
    assert length == pytest.approx(1.2 * 6.5)  # six cells, then half of the last
    # then right into the dead end of the east arm, back, and through the T again (from the east)
    third = route_passes(maze, start, "left", 3, follow_tiles=True, tile_rules=tiles)
    assert third is not None and third[2] == RoutePass(
        "right", 1, frozenset({"straight", "left", "back"})
    )
    # a walk round a loop that never drives over a tile counts no junction from a tile: None
    ring = parse_maze_text("name = ring\ncell = 1.2\n#####\n#.>.#\n#.#.#\n#...#\n#####\n")
    assert route_passes(ring, tuple(ring.starts[0]), "right", 1, count_from_tile=True) is None
