"""Mazes given by rectangles become grid mazes for the junction judge when they are one (closed,
corridors of one width, one cell wide), wherever they lie and whatever the size of their blocks;
they are refused in one line saying why when not. Judging is a pure translation: a maze and its
twins moved elsewhere (as TOML, as Stage worlds) get the same junctions, the same rule routes
and, from ``mbn evaluate``, the same verdicts, with positions in the world's own coordinates."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from mbn.cli.main import main
from mbn.controllers import CTRNNControllerSpec, save_controller
from mbn.errors import MbnInputError
from mbn.networks.ctrnn import make_ctrnn
from mbn.world.junctions import cell_of, decision_cells, junction_tables, route_passes, rule_route
from mbn.world.mazes.gridify import MAX_COORDINATE, as_grid_maze
from mbn.world.mazes.load import load_maze
from mbn.world.mazes.model import Maze, Tile, merge_grid

#: A lattice of 1.2 m corridors round 1.8 m blocks, 10.2 x 10.2 m: even rows and columns are
#: corridors, odd ones blocks ('#' between two blocks joins them): T junctions, L corners, no
#: dead end; 's' marks a start in the middle of a corridor piece.
_BLOCKS = [".s.....", ".#.###.", "s#...#.", ".###.#s", ".s...#.", ".#.#.#.", "...s..."]
_WIDTHS = np.array([1.2, 1.8, 1.2, 1.8, 1.2, 1.8, 1.2])
_START_HEADINGS = {(0, 1): 0.0, (2, 0): -math.pi / 2, (3, 6): math.pi / 2, (4, 1): 0.0}
_START_HEADINGS |= {(6, 3): math.pi}


def _blocks_maze(dx: float = 0.0, dy: float = 0.0) -> Maze:
    """The 1.2 m corridors and 1.8 m blocks of :data:`_BLOCKS`, its south-west corner at
    ``(dx, dy)``: wall rectangles, closed outside, five starts and a tile."""
    solid = np.array([[ch == "#" for ch in row] for row in _BLOCKS]) | (
        (np.arange(7)[:, None] % 2 == 1) & (np.arange(7)[None, :] % 2 == 1)
    )
    xs = dx + np.r_[0.0, np.cumsum(_WIDTHS)]
    ys = dy + np.r_[0.0, np.cumsum(_WIDTHS)]
    centre_x = (xs[:-1] + xs[1:]) / 2
    centre_y = ((ys[:-1] + ys[1:]) / 2)[::-1]  # row 0 north
    starts = [
        [centre_x[c], centre_y[r], _START_HEADINGS[(r, c)]]
        for r, row in enumerate(_BLOCKS)
        for c, ch in enumerate(row)
        if ch == "s"
    ]
    return Maze(
        "blocks",
        walls=merge_grid(solid, xs, ys),
        bounds=(xs[0], xs[-1], ys[0], ys[-1]),
        starts=starts,
        tiles=(Tile(x=float(centre_x[2]), y=float(centre_y[5]), colors=1),),
    )


def _moved(maze: Maze, dx: float, dy: float) -> Maze:
    """``maze`` (rectangles, tiles and starts) moved by ``(dx, dy)``."""
    shift = np.array([dx, dx, dy, dy])
    tiles = tuple(dataclasses.replace(t, x=t.x + dx, y=t.y + dy) for t in maze.tiles)
    return Maze(
        maze.name,
        walls=maze.walls + shift,
        bounds=tuple(np.array(maze.bounds) + shift),
        outside_is_wall=maze.outside_is_wall,
        tiles=tiles,
        starts=maze.starts + np.array([dx, dy, 0.0]),
    )


def _as_toml(maze: Maze, path: Path, scale: float = 1.0) -> Path:
    """``maze`` as a TOML file of [[free]] bounds and [[wall]] rectangles (lengths x scale)."""
    x0, x1, y0, y1 = (scale * b for b in maze.bounds)
    lines = ["[[free]]", f"xmin = {x0!r}", f"xmax = {x1!r}", f"ymin = {y0!r}", f"ymax = {y1!r}"]
    for w in maze.walls:
        keys = ("xmin", "xmax", "ymin", "ymax")
        lines += ["[[wall]]"] + [
            f"{k} = {scale * float(v)!r}" for k, v in zip(keys, w, strict=True)
        ]
    for t in maze.tiles:
        lines += ["[[tile]]", f"x = {scale * t.x!r}", f"y = {scale * t.y!r}"]
        lines += [f"colors = {t.colors}", f"heading = {math.degrees(t.heading)!r}"]
    for s in maze.starts:
        lines += ["[[start]]", f"x = {scale * float(s[0])!r}", f"y = {scale * float(s[1])!r}"]
        lines += [f"theta = {math.degrees(float(s[2]))!r}"]
    path.write_text("\n".join(lines) + "\n")
    return path


def _as_world(maze: Maze, path: Path) -> Path:
    """``maze`` as a Player/Stage world: a box model per wall (and 0.5 m thick round its bounds
    when its outside is wall), a robot per start."""
    lines = ["define wall model ( obstacle_return 1 )", ""]
    walls = maze.walls.tolist()
    if maze.outside_is_wall:
        x0, x1, y0, y1 = maze.bounds
        t = 0.5
        walls += [[x0 - t, x1 + t, y0 - t, y0], [x0 - t, x1 + t, y1, y1 + t]]
        walls += [[x0 - t, x0, y0, y1], [x1, x1 + t, y0, y1]]
    for xa, xb, ya, yb in walls:
        pose = f"[ {(xa + xb) / 2!r} {(ya + yb) / 2!r} 0 0 ]"
        lines.append(f"wall( pose {pose} size [ {xb - xa!r} {yb - ya!r} 0.5 ] )")
    for k, (x, y, th) in enumerate(maze.starts.tolist()):
        pose = f"[ {x!r} {y!r} 0 {math.degrees(th)!r} ]"
        lines.append(f'position( name "r{k}" pose {pose} size [ 0.4 0.4 0.2 ] )')
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("name", ["fig4", "heldout", "cross_LSR"])
@pytest.mark.parametrize("shift", [(0.0, 0.0), (-9.0, -6.6), (123.6, -50.4)])
def test_a_grid_maze_written_as_rectangles_comes_back_as_the_same_grid_where_it_lies(
    tmp_path, name, shift
):
    maze = load_maze(name)
    moved = _moved(maze, *shift)
    again = as_grid_maze(load_maze(_as_toml(moved, tmp_path / f"{name}.toml")))
    assert again.cell == pytest.approx(maze.cell, abs=1e-12) and again.edges is None
    np.testing.assert_array_equal(again.grid == "#", maze.grid == "#")
    np.testing.assert_allclose(again.walls, moved.walls, atol=1e-9)
    assert again.bounds == pytest.approx(moved.bounds, abs=1e-9)
    np.testing.assert_allclose(again.starts, moved.starts, atol=1e-9)  # the world's own places
    assert len(again.tiles) == len(maze.tiles)


def test_a_maze_of_1_2_m_corridors_and_1_8_m_blocks_is_a_grid_of_those_widths():
    grid = as_grid_maze(_blocks_maze())
    assert grid.cell is None and grid.edges is not None
    xs, ys = grid.edges
    np.testing.assert_allclose(np.diff(xs), _WIDTHS, atol=1e-12)
    np.testing.assert_allclose(np.diff(ys), _WIDTHS, atol=1e-12)
    assert ["".join(r) for r in grid.grid] == [row.replace("s", ".") for row in _BLOCKS]
    # decision cells: where corridors cross, but not where one runs straight on (row 2, col 0)
    dec = decision_cells(grid)
    assert dec[0, 2] and dec[2, 4] and not dec[2, 0] and int(dec.sum()) == 12
    assert int(dec[1::2].sum() + dec[:, 1::2].sum()) == 0  # the pieces between blocks: none
    assert cell_of(grid, xs[4] + 0.01, ys[5] + 0.01) == (1, 4)  # x 6..7.2, y 7.2..9 (row 1)
    assert cell_of(grid, xs[4], ys[4]) == (2, 4)  # a border point: the cell east and north
    # a route centre to centre: from start 1 (row 0, column 1, facing east) the right rule
    # turns south at the T (row 0, column 2) and east at the corner below it (row 2, column 2):
    # 0.9 + 0.6, 0.6 + 0.9, 0.9 + 0.6, and half the corner cell
    assert rule_route(grid, tuple(grid.starts[0]), "right", 2) == pytest.approx(5.1, abs=1e-9)


@pytest.mark.parametrize("which", ["fig4", "blocks"])
def test_judging_is_a_pure_translation(which):
    """The same maze at the origin, centred on it and far off: the same grid, decision cells,
    rule tables, routes (to 1e-9 m) and junctions judged from every start, each start in the
    cell of the same grid it lies in."""
    if which == "fig4":
        f4 = load_maze("fig4")
        base = Maze("fig4", walls=f4.walls, bounds=f4.bounds, tiles=f4.tiles, starts=f4.starts)
        width, height = f4.bounds[1], f4.bounds[3]
    else:
        base = _blocks_maze()
        width = height = float(_WIDTHS.sum())
    twins = [as_grid_maze(_moved(base, dx, dy)) for dx, dy in [(0, 0), (-width / 2, -height / 2)]]
    twins.append(as_grid_maze(_moved(base, -MAX_COORDINATE + width, 977.7)))
    first = twins[0]
    for twin in twins[1:]:
        np.testing.assert_array_equal(twin.grid, first.grid)
        for key, table in junction_tables(first).items():
            np.testing.assert_array_equal(junction_tables(twin)[key], table)
        for s0, s1 in zip(first.starts, twin.starts, strict=True):
            assert cell_of(twin, s1[0], s1[1]) == cell_of(first, s0[0], s0[1])
            for rule in ("right", "left", "straight-right"):
                a = rule_route(first, tuple(s0), rule, 3)
                b = rule_route(twin, tuple(s1), rule, 3)
                assert (a is None) == (b is None) and (a is None or abs(a - b) < 1e-9)
                assert route_passes(twin, tuple(s1), rule, 3) == route_passes(
                    first, tuple(s0), rule, 3
                )


def _evaluate(capsys, controller: Path, maze: str, *, text: bool = False) -> dict | list[str]:
    """``mbn evaluate`` of ``controller`` in ``maze`` (by the right rule, 2 trials a start): the
    JSON object, or with ``text`` the report's lines."""
    argv = ["evaluate", "--controller", str(controller), "--maze", maze, "--repeats", "2"]
    argv += ["--behavior", "right"] + ([] if text else ["--json"])
    assert main(argv) == 0
    out = capsys.readouterr().out
    return out.splitlines() if text else json.loads(out)


@pytest.fixture(scope="session")
def straight(tmp_path_factory) -> Path:
    """A controller that drives straight ahead (it crosses junctions, and stalls at walls)."""
    path = tmp_path_factory.mktemp("controllers") / "c.json"
    drive = make_ctrnn(np.zeros((3, 3)), np.zeros((3, 3)), 0.5, bias=[0.0, 0.0, 3.0])
    save_controller(path, CTRNNControllerSpec(drive, behavior="right"))
    return path


@pytest.mark.slow  # three whole evaluations; the twins' grids are compared cell by cell above
def test_mbn_evaluate_gives_fig4_and_its_moved_twins_the_same_verdicts(tmp_path, capsys, straight):
    """fig4 itself, and centred on the origin as TOML (a grid of 1.2 m cells) and as a Stage
    world (framed by 0.5 m walls: a grid of two widths): the same trials, junction passes and
    successes; the report shows the twin's starts where they lie."""
    centred = _moved(load_maze("fig4"), -9.0, -6.6)
    toml = str(_as_toml(centred, tmp_path / "c.toml"))
    world = str(_as_world(centred, tmp_path / "c.world"))
    results = [_evaluate(capsys, straight, maze) for maze in ("fig4", toml, world)]
    assert results[0]["junctions"] > 0  # the test judges something
    assert results[1] == results[0] and results[2] == results[0]
    lines = _evaluate(capsys, straight, world, text=True)
    assert lines[1].startswith("  start  1 at (-4.80, 4.80) facing E:")  # fig4's (4.2, 11.4)


@pytest.mark.slow
def test_mbn_evaluate_gives_a_maze_of_1_8_m_blocks_the_same_verdicts_wherever_it_lies(
    tmp_path, capsys, straight
):
    """1.2 m corridors round 1.8 m blocks as TOML at the origin, and as a Stage world centred on
    it and moved to (5.1, 5.1) of it: the same verdicts, and junctions are judged."""
    half = float(_WIDTHS.sum()) / 2
    toml = str(_as_toml(_blocks_maze(), tmp_path / "blocks.toml"))
    centred = str(_as_world(_blocks_maze(-half, -half), tmp_path / "centred.world"))
    shifted = str(_as_world(_blocks_maze(half, half), tmp_path / "shifted.world"))
    results = [_evaluate(capsys, straight, maze) for maze in (toml, centred, shifted)]
    assert results[0]["junctions"] > 0
    assert results[1] == results[0] and results[2] == results[0]
    lines = _evaluate(capsys, straight, centred, text=True)
    assert lines[1].startswith("  start 1 at (-3.00, 4.50) facing E:")  # -5.1 + 2.1, 5.1 - 0.6


def _not_grids() -> dict[str, tuple[Maze, str]]:
    return {
        "docs": (
            Maze("d", walls=[[2.0, 2.4, 0.0, 0.3]], bounds=(0.0, 6.0, 0.0, 1.2)),
            "maze 'd': its corridors are not all one width: 0.9 m at x 0..2, y 0.3..1.2, 2 m at "
            "x 0..2, y 0..0.3; junction judging needs corridors of one width",
        ),
        "wide corridor": (
            Maze("w", walls=[[2.4, 3.6, 1.2, 4.8]], bounds=(0.0, 6.0, 0.0, 6.0)),
            "maze 'w': its corridors are not all one width: 1.2 m at x 0..2.4, y 0..1.2, 2.4 m "
            "at x 0..2.4, y 1.2..4.8; junction judging needs corridors of one width",
        ),
        "two cells across": (
            Maze(
                "t",
                walls=[[1.2, 2.4, 1.2, 3.6], [3.6, 4.8, 0.0, 2.4], [0.0, 1.2, 4.8, 6.0]],
                bounds=(0.0, 6.0, 0.0, 6.0),
            ),
            "maze 't': the free space at x 1.2..3.6, y 3.6..6 is two cells across (the edges "
            "of its walls cut it at x 2.4, y 4.8); junction judging needs corridors one cell "
            "wide",
        ),
        "open": (
            Maze("o", [[0.0, 1.2, 0.0, 1.2]], (0.0, 3.6, 0.0, 3.6), outside_is_wall=False),
            "maze 'o': its outside is open (walls only, and free space reaches its bounds); "
            "junction judging needs a closed maze",
        ),
        "far": (
            Maze("far", walls=np.zeros((0, 4)), bounds=(0.0, 1.2, -1e300, 1.2)),
            "maze 'far': its bounds reach 1e+300 m from the origin; junction judging needs a "
            "maze within 10000 m of it",
        ),
    }


@pytest.mark.parametrize("case", list(_not_grids()))
def test_a_maze_that_is_not_a_grid_of_corridors_is_refused_saying_why(case):
    maze, message = _not_grids()[case]
    with pytest.raises(MbnInputError) as exc:
        as_grid_maze(maze)
    assert str(exc.value) == message


def test_a_toml_coordinate_of_1e300_is_one_line_and_exit_2(tmp_path, capsys, straight):
    """A free rectangle reaching x = 1e300: refused in one line; a wall out there beyond the
    free rectangles is outside the maze, and the maze is judged."""
    far = tmp_path / "far.toml"
    far.write_text(
        "[[free]]\nxmin = 0.0\nxmax = 1e300\nymin = 0.0\nymax = 1.2\n"
        "[[start]]\nx = 0.6\ny = 0.6\ntheta = 0\n"
    )
    argv = ["evaluate", "--controller", str(straight), "--behavior", "right", "--seconds", "5"]
    assert main([*argv, "--maze", str(far)]) == 2
    err = capsys.readouterr().err
    assert err == (
        "mbn: error: maze 'far': its bounds reach 1e+300 m from the origin; junction judging "
        "needs a maze within 10000 m of it\n"
    )
    beyond = tmp_path / "beyond.toml"
    beyond.write_text(
        "[[free]]\nxmin = 0.0\nxmax = 3.6\nymin = 0.0\nymax = 1.2\n"
        "[[wall]]\nxmin = 1e300\nxmax = 2e300\nymin = 0.0\nymax = 1.2\n"
        "[[start]]\nx = 0.6\ny = 0.6\ntheta = 0\n"
    )
    assert main([*argv, "--maze", str(beyond), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["trials"] == 1


def test_the_stage_arena_is_judged_as_a_grid_of_its_corridors():
    """The reference arena (1.2 m corridors between blocks of 3 to 6.6 m) is a grid of those
    widths; its starts lie in corridor cells, where it lies."""
    grid = as_grid_maze(load_maze("stage_arena"))
    xs, ys = grid.edges
    np.testing.assert_allclose(xs, [0, 1, 4, 5.2, 9.4, 10.6, 11.8, 13, 14], atol=1e-12)
    np.testing.assert_allclose(ys, [0, 1, 4.6, 5.8, 8.2, 9.4, 10.4], atol=1e-12)
    assert ["".join(r) for r in grid.grid][1:5] == ["##.#...#", "##.#.###", "#......#", "##.###.#"]
    for x, y, _ in grid.starts:
        r, c = cell_of(grid, x, y)
        assert grid.grid[r, c] == "."


def test_mbn_evaluate_help_states_the_rule(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["evaluate", "--help"])
    assert exc.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert (
        "a .toml or .world maze is judged when it is a grid of corridors: closed, every corridor "
        "one width and one cell wide, blocks of any size, anywhere within 10 km of the origin"
    ) in text
