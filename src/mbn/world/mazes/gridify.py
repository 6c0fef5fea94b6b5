"""A maze given by rectangles (TOML, Player/Stage) as a grid maze, when it is one: the junction
judge (:mod:`mbn.world.junctions`) needs a grid of corridors one cell wide.

:func:`as_grid_maze` draws a line through every wall edge (and the bounds), drops the lines that
separate nothing (the two sides alike in every row or column), and accepts the grid of cells left
when it is a grid of corridors (``docs/mazes.md``, "Which mazes can be judged"):

* the maze is closed: its outside is wall, or no free space reaches its bounds;
* no free space is two cells across (no 2 x 2 block of free cells);
* every corridor has one width ``w``: a free cell between walls on its north and south sides is
  ``w`` tall, one between walls on its east and west sides ``w`` wide, and any other free cell
  (a junction, a corner) ``w`` x ``w``; blocks (and a corridor's length) may be of any size;
* its bounds lie within :data:`MAX_COORDINATE` of the origin (the rollout's positions are
  float32), and the grid has at most :data:`MAX_GRID_CELLS` cells.

The grid lies where the maze lies (nothing is moved: positions keep the world's coordinates).
When every column and row is a whole number of corridor widths, the grid is one of square cells
``w`` wide (``cell``, as a ``.maze`` file: a maze written as rectangles comes back as its
``.maze`` twin); otherwise its columns and rows keep their widths (``edges``). Anything else is
refused in one line saying which rule fails and where, in the world's coordinates.
"""

from __future__ import annotations

import numpy as np

from mbn.errors import MbnInputError
from mbn.world.mazes.model import Maze, merge_cells, merge_grid

__all__ = ["MAX_COORDINATE", "MAX_GRID_CELLS", "WIDTH_TOLERANCE", "as_grid_maze"]

#: The most cells a maze's grid may have (before and after splitting it into square cells).
MAX_GRID_CELLS = 4_000_000
#: How far from the origin (metres) a judged maze's bounds may lie: the rollout's positions are
#: float32, about 1 mm apart at 10 km.
MAX_COORDINATE = 10_000.0
#: Widths that differ by at most this much (metres) are one width.
WIDTH_TOLERANCE = 1e-6


def _lines(values: np.ndarray, tol: float) -> np.ndarray:
    """The distinct ``values``, sorted; values within ``tol`` of the one before are one line."""
    v = np.unique(values)
    keep = np.ones(len(v), bool)
    keep[1:] = np.diff(v) > tol
    return v[keep]


def _raster(walls: np.ndarray, xs: np.ndarray, ys: np.ndarray, tol: float) -> np.ndarray:
    """Solid cells ``(R, C)`` (first row north) of the grid of lines ``xs``, ``ys``: the cells
    the ``walls`` cover (a 2-D difference array: linear in walls and cells)."""
    cols, rows = len(xs) - 1, len(ys) - 1
    c0 = np.searchsorted(xs, walls[:, 0] - tol)
    c1 = np.searchsorted(xs, walls[:, 1] - tol)
    j0 = np.searchsorted(ys, walls[:, 2] - tol)  # from the south
    j1 = np.searchsorted(ys, walls[:, 3] - tol)
    cover = np.zeros((rows + 1, cols + 1), np.int64)
    np.add.at(cover, (j0, c0), 1)
    np.add.at(cover, (j0, c1), -1)
    np.add.at(cover, (j1, c0), -1)
    np.add.at(cover, (j1, c1), 1)
    solid_south_first = np.cumsum(np.cumsum(cover, 0), 1)[:rows, :cols] > 0
    return solid_south_first[::-1]


def _drop_lines(edges: np.ndarray, solid: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """Drop the lines between two columns (``axis=1``) or rows (``axis=0``) that are alike."""
    if axis == 1:
        alike = np.all(solid[:, 1:] == solid[:, :-1], axis=0)
        keep = np.r_[True, ~alike]
        return np.r_[edges[:-1][keep], edges[-1]], solid[:, keep]
    # rows: row r spans edges[R - 1 - r] .. edges[R - r]; compare from the south
    south = solid[::-1]
    alike = np.all(south[1:] == south[:-1], axis=1)
    keep = np.r_[True, ~alike]
    return np.r_[edges[:-1][keep], edges[-1]], south[keep][::-1]


def _span(lo: float, hi: float) -> str:
    return f"{lo:g}..{hi:g}"


def as_grid_maze(maze: Maze) -> Maze:
    """``maze`` itself if it has a grid, else the same world as a grid maze (walls merged from
    the grid, same tiles and starts, same place), or a one-line :class:`MbnInputError` saying
    which rule of the module docstring it breaks and where."""
    if maze.grid is not None:
        return maze
    what = f"maze {maze.name!r}"
    x0, x1, y0, y1 = maze.bounds
    far = max(abs(x0), abs(x1), abs(y0), abs(y1))
    if far > MAX_COORDINATE:
        raise MbnInputError(
            f"{what}: its bounds reach {far:g} m from the origin; junction judging needs a maze "
            f"within {MAX_COORDINATE:g} m of it"
        )
    tol = 1e-9 * max(1.0, far)
    w = maze.walls
    w = w[(w[:, 1] > x0 + tol) & (w[:, 0] < x1 - tol) & (w[:, 3] > y0 + tol) & (w[:, 2] < y1 - tol)]
    w = np.clip(w, [x0, x0, y0, y0], [x1, x1, y1, y1])
    xs = _lines(np.r_[x0, x1, w[:, 0], w[:, 1]], tol)
    ys = _lines(np.r_[y0, y1, w[:, 2], w[:, 3]], tol)
    if (len(xs) - 1) * (len(ys) - 1) > MAX_GRID_CELLS:
        raise MbnInputError(
            f"{what}: the edges of its walls cut it into {len(xs) - 1} x {len(ys) - 1} cells, "
            f"more than the {MAX_GRID_CELLS // 1_000_000} M junction judging takes"
        )
    solid = _raster(w, xs, ys, tol)
    if not maze.outside_is_wall:
        free = ~solid
        if free[0].any() or free[-1].any() or free[:, 0].any() or free[:, -1].any():
            raise MbnInputError(
                f"{what}: its outside is open (walls only, and free space reaches its bounds); "
                "junction judging needs a closed maze"
            )
    xs, solid = _drop_lines(xs, solid, axis=1)
    ys, solid = _drop_lines(ys, solid, axis=0)
    rows, cols = solid.shape
    free = ~solid
    if not free.any():
        raise MbnInputError(f"{what}: no free space; junction judging needs corridors")

    def box(r: int, c: int, n_rows: int = 1, n_cols: int = 1) -> str:
        """Where cells ``r .. r + n_rows - 1`` x ``c .. c + n_cols - 1`` lie, in metres."""
        return f"x {_span(xs[c], xs[c + n_cols])}, y {_span(ys[rows - r - n_rows], ys[rows - r])}"

    block = free[:-1, :-1] & free[1:, :-1] & free[:-1, 1:] & free[1:, 1:]
    if block.any():
        r, c = (int(v) for v in np.argwhere(block)[0])
        raise MbnInputError(
            f"{what}: the free space at {box(r, c, 2, 2)} is two cells across (the edges of its "
            f"walls cut it at x {xs[c + 1]:g}, y {ys[rows - r - 1]:g}); junction judging needs "
            "corridors one cell wide"
        )
    width = np.diff(xs)[None, :].repeat(rows, 0)  # (R, C)
    height = np.diff(ys)[::-1][:, None].repeat(cols, 1)
    walled = np.pad(solid, 1, constant_values=True)
    ns = walled[:-2, 1:-1] & walled[2:, 1:-1]  # walls north and south: an east-west corridor
    ew = walled[1:-1, :-2] & walled[1:-1, 2:]
    # what each free cell must measure across its corridor: between walls north and south, its
    # height; between walls east and west, its width; walled on all four sides, the smaller;
    # otherwise (a junction, a corner) both
    first = np.where(ns & ew, np.minimum(width, height), np.where(ew, width, height))
    first = np.where(free, first, np.nan)
    second = np.where(free & ~ns & ~ew, width, np.nan)
    needs = np.stack([first, second])  # (2, R, C)
    k0, r0, c0 = (int(v) for v in np.unravel_index(int(np.nanargmin(needs)), needs.shape))
    corridor = float(needs[k0, r0, c0])
    wrong = np.abs(needs - corridor) > WIDTH_TOLERANCE  # NaN compares False
    if wrong.any():
        k, r, c = (int(v) for v in np.argwhere(wrong)[0])
        raise MbnInputError(
            f"{what}: its corridors are not all one width: {corridor:g} m at "
            f"{box(r0, c0)}, {needs[k, r, c]:g} m at {box(r, c)}; junction "
            "judging needs corridors of one width"
        )
    cell = float(np.round(corridor, 9))
    per_col = np.diff(xs) / cell
    per_row = np.diff(ys)[::-1] / cell
    k_col, k_row = np.rint(per_col), np.rint(per_row)
    if np.all(np.abs(per_col - k_col) * cell <= WIDTH_TOLERANCE) and np.all(
        np.abs(per_row - k_row) * cell <= WIDTH_TOLERANCE
    ):
        n_cols, n_rows = int(k_col.sum()), int(k_row.sum())
        if n_cols * n_rows > MAX_GRID_CELLS:
            raise MbnInputError(
                f"{what}: {n_cols} x {n_rows} cells of {cell:g} m, more than the "
                f"{MAX_GRID_CELLS // 1_000_000} M junction judging takes"
            )
        square = np.repeat(np.repeat(solid, k_row.astype(int), 0), k_col.astype(int), 1)
        return Maze(
            name=maze.name,
            walls=merge_cells(square, cell, origin=(x0, y0)),
            bounds=(x0, x0 + n_cols * cell, y0, y0 + n_rows * cell),
            outside_is_wall=True,
            tiles=maze.tiles,
            starts=maze.starts,
            grid=np.where(square, "#", "."),
            cell=cell,
            source=maze.source,
        )
    return Maze(
        name=maze.name,
        walls=merge_grid(solid, xs, ys),
        bounds=(float(xs[0]), float(xs[-1]), float(ys[0]), float(ys[-1])),
        outside_is_wall=True,
        tiles=maze.tiles,
        starts=maze.starts,
        grid=np.where(solid, "#", "."),
        source=maze.source,
        edges=(xs, ys),
    )
