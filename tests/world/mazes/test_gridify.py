"""Mazes given by rectangles become grid mazes for the junction judge when they are one (a
lattice of one-cell corridors, closed), and are refused in one line saying why when not."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from mbn.cli.main import main
from mbn.controllers import CTRNNControllerSpec, save_controller
from mbn.errors import MbnInputError
from mbn.networks.ctrnn import make_ctrnn
from mbn.world.mazes.gridify import as_grid_maze
from mbn.world.mazes.load import load_maze
from mbn.world.mazes.model import Maze


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


@pytest.mark.parametrize("name", ["fig4", "heldout", "cross_LSR"])
def test_a_grid_maze_written_as_rectangles_comes_back_as_the_same_grid(tmp_path, name):
    maze = load_maze(name)
    again = as_grid_maze(load_maze(_as_toml(maze, tmp_path / f"{name}.toml")))
    assert again.cell == pytest.approx(maze.cell, abs=1e-12)
    np.testing.assert_array_equal(again.grid == "#", maze.grid == "#")
    np.testing.assert_allclose(again.walls, maze.walls, atol=1e-9)
    assert again.bounds == pytest.approx(maze.bounds)
    np.testing.assert_allclose(again.starts, maze.starts, atol=1e-9)
    assert len(again.tiles) == len(maze.tiles)


def test_mbn_evaluate_judges_a_toml_maze_as_its_grid_twin(tmp_path, capsys):
    drive = make_ctrnn(np.zeros((3, 3)), np.zeros((3, 3)), 0.5, bias=[0.0, 0.4, 3.0])
    save_controller(tmp_path / "c.json", CTRNNControllerSpec(drive, behavior="right"))
    toml = _as_toml(load_maze("fig4"), tmp_path / "fig4.toml")
    results = []
    for maze in ("fig4", str(toml)):
        argv = ["evaluate", "--controller", str(tmp_path / "c.json"), "--maze", maze]
        assert main([*argv, "--behavior", "right", "--repeats", "2", "--json"]) == 0
        results.append(json.loads(capsys.readouterr().out))
    assert results[0] == results[1]
    assert results[0]["junctions"] > 0  # the test judges something


@pytest.mark.parametrize(
    ("maze", "words"),
    [
        ("stage_arena", "its corridors are wider than one cell of its 0.2 m lattice"),
        ("docs", "its corridors are wider than one cell of its 0.1 m lattice"),
        ("open", "its outside is open"),
        ("negative", "its bounds start at (-1.2, 0)"),
    ],
)
def test_a_maze_that_is_not_a_grid_of_corridors_is_refused_saying_why(tmp_path, maze, words):
    if maze == "stage_arena":
        m = load_maze("stage_arena")
    elif maze == "docs":
        m = Maze("d", walls=[[2.0, 2.4, 0.0, 0.3]], bounds=(0.0, 6.0, 0.0, 1.2))
    elif maze == "open":
        m = Maze(
            "o", walls=[[0.0, 1.2, 0.0, 1.2]], bounds=(0.0, 3.6, 0.0, 3.6), outside_is_wall=False
        )
    else:
        m = Maze("n", walls=[[0.0, 1.2, 0.0, 1.2]], bounds=(-1.2, 3.6, 0.0, 3.6))
    with pytest.raises(MbnInputError) as exc:
        as_grid_maze(m)
    assert words in str(exc.value) and "\n" not in str(exc.value)


def _as_world(maze: Maze, path: Path) -> Path:
    """``maze`` as a Player/Stage world: a box model per wall, a robot per start."""
    lines = ["define wall model ( obstacle_return 1 )", ""]
    for xa, xb, ya, yb in maze.walls.tolist():
        pose = f"[ {(xa + xb) / 2!r} {(ya + yb) / 2!r} 0 0 ]"
        lines.append(f"wall( pose {pose} size [ {xb - xa!r} {yb - ya!r} 0.5 ] )")
    for k, (x, y, th) in enumerate(maze.starts.tolist()):
        pose = f"[ {x!r} {y!r} 0 {math.degrees(th)!r} ]"
        lines.append(f'position( name "r{k}" pose {pose} size [ 0.4 0.4 0.2 ] )')
    path.write_text("\n".join(lines) + "\n")
    return path


def test_mbn_evaluate_judges_a_stage_world_as_its_grid_twin(tmp_path, capsys):
    drive = make_ctrnn(np.zeros((3, 3)), np.zeros((3, 3)), 0.5, bias=[0.0, 0.4, 3.0])
    save_controller(tmp_path / "c.json", CTRNNControllerSpec(drive, behavior="right"))
    world = _as_world(load_maze("fig4"), tmp_path / "fig4.world")
    results = []
    for maze in ("fig4", str(world)):
        argv = ["evaluate", "--controller", str(tmp_path / "c.json"), "--maze", maze]
        assert main([*argv, "--behavior", "right", "--repeats", "2", "--json"]) == 0
        results.append(json.loads(capsys.readouterr().out))
    assert results[0] == results[1] and results[0]["junctions"] > 0
