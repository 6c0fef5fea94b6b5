"""Mazes the picture tests draw: a T junction with tiles and starts, and a corridor."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mbn.world.mazes.model import Maze, Tile, merge_cells

CELL = 1.2


def grid_maze(rows: list[str], name: str, **kw: object) -> Maze:
    grid = np.array([list(r) for r in rows])
    r, c = grid.shape
    return Maze(
        name=name,
        walls=merge_cells(grid == "#", CELL),
        bounds=(0.0, c * CELL, 0.0, r * CELL),
        grid=grid,
        cell=CELL,
        **kw,  # type: ignore[arg-type]
    )


@pytest.fixture(scope="session")
def tee() -> Maze:
    """A T junction: a corridor west-east on row 1, a stem going south from its middle."""
    return grid_maze(
        ["#####", "#...#", "##.##", "##.##", "#####"],
        "tee",
        tiles=(Tile(3.0, 2.4, 1, heading=math.pi / 2), Tile(1.8, 4.2, 2, heading=0.0)),
        starts=[[3.0, 1.8, math.pi / 2], [1.8, 4.2, 0.0]],
    )


@pytest.fixture(scope="session")
def corridor() -> Maze:
    """A corridor 1.2 m wide along x, from x = 1.2 to 7.2."""
    return grid_maze(["#######", "#.....#", "#######"], "corridor", starts=[[2.0, 1.8, 0.0]])
