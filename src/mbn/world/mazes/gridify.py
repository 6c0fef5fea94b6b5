"""A maze given by rectangles (TOML, Player/Stage) as a grid maze, when it is one: the junction
judge (:mod:`mbn.world.junctions`) needs a grid of one-cell corridors.

:func:`as_grid_maze` finds the coarsest lattice its walls and bounds lie on (the greatest common
divisor of every coordinate), rasterises the solid region on it, and accepts it when every
corridor is one cell wide (no 2 x 2 block of free cells) and the outside is closed. Otherwise it
refuses in one line saying which of these fails and where.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from mbn.errors import MbnInputError
from mbn.world.mazes.model import Maze, merge_cells

__all__ = ["MAX_GRID_CELLS", "as_grid_maze"]

#: The most cells a rasterised maze may have (a finer lattice is not a maze of corridors).
MAX_GRID_CELLS = 4_000_000


def _lattice(values: np.ndarray) -> float:
    """The largest ``g`` of which every value is a whole multiple (to 1e-9 m)."""
    g = Fraction(0)
    for v in np.unique(np.round(np.abs(values), 9)):
        f = Fraction(float(v)).limit_denominator(10**6)
        if abs(float(f) - float(v)) > 1e-9:
            return 0.0
        g = (
            Fraction(
                math.gcd(g.numerator * f.denominator, f.numerator * g.denominator),
                g.denominator * f.denominator,
            )
            if g
            else f
        )
    return float(g)


def as_grid_maze(maze: Maze) -> Maze:
    """``maze`` itself if it has a grid, else the same world as a grid maze (walls merged from
    the grid, same tiles and starts), or a one-line :class:`MbnInputError` saying why it is not
    one."""
    if maze.grid is not None:
        return maze
    what = f"maze {maze.name!r}"
    x0, x1, y0, y1 = maze.bounds
    if x0 < 0 or y0 < 0:
        raise MbnInputError(
            f"{what}: its bounds start at ({x0:g}, {y0:g}); junction judging needs a grid with "
            "its south-west corner at x, y >= 0"
        )
    w = maze.walls
    coords = np.concatenate(
        [[x0, x1, y0, y1], np.clip(w[:, :2], x0, x1).ravel(), np.clip(w[:, 2:], y0, y1).ravel()]
    )
    cell = _lattice(coords[coords > 0])
    cols = round(x1 / cell) if cell > 0 else 0
    rows = round(y1 / cell) if cell > 0 else 0
    if cell <= 0 or rows * cols > MAX_GRID_CELLS:
        raise MbnInputError(
            f"{what}: its walls lie on no lattice coarser than "
            f"{MAX_GRID_CELLS // 1_000_000} M cells; junction judging needs a grid of corridors"
        )
    cx = (np.arange(cols) + 0.5) * cell
    cy = (np.arange(rows)[::-1] + 0.5) * cell  # row 0 north
    inside = (cx[None, :] > x0) & (cx[None, :] < x1) & (cy[:, None] > y0) & (cy[:, None] < y1)
    solid = ~inside if maze.outside_is_wall else np.zeros((rows, cols), bool)
    for xa, xb, ya, yb in w:
        c0, c1 = round(max(xa, 0) / cell), round(min(xb, x1) / cell)
        r0, r1 = rows - round(min(yb, y1) / cell), rows - round(max(ya, 0) / cell)
        solid[max(r0, 0) : max(r1, 0), max(c0, 0) : max(c1, 0)] = True
    free = ~solid
    if not maze.outside_is_wall and (
        free[0].any() or free[-1].any() or free[:, 0].any() or free[:, -1].any()
    ):
        raise MbnInputError(
            f"{what}: its outside is open (walls only, and free space reaches its bounds); "
            "junction judging needs a closed maze"
        )
    block = free[:-1, :-1] & free[1:, :-1] & free[:-1, 1:] & free[1:, 1:]
    if block.any():
        r, c = (int(v) for v in np.argwhere(block)[0])
        raise MbnInputError(
            f"{what}: its corridors are wider than one cell of its {cell:g} m lattice (free "
            f"{2 * cell:g} x {2 * cell:g} m at x {c * cell:g}..{(c + 2) * cell:g}, y "
            f"{(rows - r - 2) * cell:g}..{(rows - r) * cell:g}); junction judging needs "
            "corridors one cell wide"
        )
    grid = np.where(solid, "#", ".")
    return Maze(
        name=maze.name,
        walls=merge_cells(solid, cell),
        bounds=(0.0, cols * cell, 0.0, rows * cell),
        outside_is_wall=True,
        tiles=maze.tiles,
        starts=maze.starts,
        grid=grid,
        cell=cell,
        source=maze.source,
    )
