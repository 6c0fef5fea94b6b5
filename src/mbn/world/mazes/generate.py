"""Generated grid mazes: corridors one cell wide crossing at right angles, of any size.

:func:`corridor_maze` carves a random spanning tree of corridors (depth-first search on the odd
cells of the grid, so corridors are one cell wide and meet at right angles) and then opens a
fraction of the remaining walls between corridors, which makes loops, T junctions and
crossings. The result is reproducible from its seed.
"""

from __future__ import annotations

import numpy as np

from mbn.errors import MbnInputError
from mbn.world.mazes.model import DEFAULT_CELL, Maze, merge_cells

__all__ = ["corridor_maze"]


def corridor_maze(
    cols: int,
    rows: int,
    *,
    seed: int = 0,
    loops: float = 0.1,
    cell: float = DEFAULT_CELL,
    starts: int = 8,
    name: str | None = None,
) -> Maze:
    """A ``rows x cols`` grid maze (cells of ``cell`` metres) with one-cell-wide corridors.

    Args:
        cols, rows: grid size in cells (at least 5 each); the outer ring is wall.
        seed: seed of the layout (NumPy generator, at this edge of the library).
        loops: fraction of inner walls between two corridors to knock through.
        cell: cell side (metres).
        starts: number of start poses, at random corridor cells facing along the corridor.
        name: defaults to ``corridor_{cols}x{rows}_s{seed}``.
    """
    if cols < 5 or rows < 5:
        raise MbnInputError(f"corridor_maze needs at least 5 x 5 cells, got {cols} x {rows}")
    if not 0.0 <= loops <= 1.0:
        raise MbnInputError(f"loops must be in [0, 1], got {loops!r}")
    rng = np.random.default_rng(seed)
    free = np.zeros((rows, cols), dtype=bool)
    nr, nc = (rows - 1) // 2, (cols - 1) // 2
    seen = np.zeros((nr, nc), dtype=bool)
    stack = [(0, 0)]
    seen[0, 0] = True
    free[1, 1] = True
    while stack:
        r, c = stack[-1]
        options = [
            (r + dr, c + dc)
            for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1))
            if 0 <= r + dr < nr and 0 <= c + dc < nc and not seen[r + dr, c + dc]
        ]
        if not options:
            stack.pop()
            continue
        nr_, nc_ = options[rng.integers(len(options))]
        seen[nr_, nc_] = True
        free[2 * nr_ + 1, 2 * nc_ + 1] = True
        free[r + nr_ + 1, c + nc_ + 1] = True
        stack.append((nr_, nc_))
    # knock through some walls that separate two corridor cells in a line
    for r in range(1, rows - 1):
        for c in range(1, cols - 1):
            if free[r, c]:
                continue
            horizontal = (
                free[r, c - 1] and free[r, c + 1] and not free[r - 1, c] and not free[r + 1, c]
            )
            vertical = (
                free[r - 1, c] and free[r + 1, c] and not free[r, c - 1] and not free[r, c + 1]
            )
            if (horizontal or vertical) and rng.random() < loops:
                free[r, c] = True
    grid = np.where(free, ".", "#").astype("<U1")
    poses = []
    cells = np.argwhere(free)
    for r, c in cells[rng.permutation(len(cells))][: max(0, starts)]:
        x, y = (c + 0.5) * cell, (rows - r - 0.5) * cell
        if free[r - 1, c] or free[r + 1, c]:
            theta = np.pi / 2 if free[r - 1, c] else -np.pi / 2
        else:
            theta = 0.0 if free[r, c + 1] else np.pi
        poses.append((x, y, theta))
    return Maze(
        name=name or f"corridor_{cols}x{rows}_s{seed}",
        walls=merge_cells(~free, cell),
        bounds=(0.0, cols * cell, 0.0, rows * cell),
        outside_is_wall=True,
        starts=np.array(poses, dtype=float).reshape(-1, 3),
        grid=grid,
        cell=cell,
        source="generated",
    )
