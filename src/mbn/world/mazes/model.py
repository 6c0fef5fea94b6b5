"""Mazes: wall rectangles, coloured floor tiles and start poses (the data every other part reads).

A :class:`Maze` is plain immutable data in SI units (metres, radians; x east, y north). Walls are
solid axis-aligned rectangles ``(xmin, xmax, ymin, ymax)``; ``outside_is_wall`` says whether the
space outside ``bounds`` is solid (grid and ``[[free]]`` mazes) or open (mazes given by walls only).
Mazes read from a ``.maze`` grid also keep the grid itself (``grid``, ``cell``) for junction
analysis; a maze given by rectangles becomes such a grid maze when it is one
(:mod:`mbn.world.mazes.gridify`), its grid then lying wherever its bounds lie and, when its blocks
are not whole multiples of its corridor width, with columns and rows of more than one width
(``edges``). Files are read by :mod:`mbn.world.mazes.load`; the built-in mazes are in
:mod:`mbn.world.mazes.builtin`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mbn.errors import MbnInputError

__all__ = [
    "DEFAULT_CELL",
    "DEFAULT_TILE_LENGTH",
    "TILE_COLORS",
    "Maze",
    "Tile",
    "merge_cells",
    "merge_grid",
]

#: Default side of a grid cell: three Pioneer 3DX widths (3 x 0.4 m), the paper's corridor width.
DEFAULT_CELL = 1.2
#: Default extent of a tile along the corridor (metres).
DEFAULT_TILE_LENGTH = 0.3
#: The tile kinds: how many colours (blobs side by side across the corridor) a tile shows.
TILE_COLORS = (1, 2, 3, 4, 5, 6)


@dataclass(frozen=True)
class Tile:
    """A coloured strip on the floor, across a corridor.

    ``(x, y)`` is its centre; ``heading`` the direction along the corridor (radians); ``width`` its
    extent across the corridor and ``length`` along it. ``colors`` is 1 (one-colour tile), 2 (a
    two-colour tile: two halves side by side across the corridor, so that a camera sees two blobs),
    3 (three thirds, three blobs) and so on up to 6: a tile of ``c`` colours is ``c`` equal parts
    side by side across the corridor (:data:`TILE_COLORS`).
    """

    x: float
    y: float
    colors: int
    width: float = DEFAULT_CELL
    length: float = DEFAULT_TILE_LENGTH
    heading: float = math.pi / 2

    def __post_init__(self) -> None:
        if self.colors not in TILE_COLORS:
            raise MbnInputError(
                f"tile colors must be an integer from {TILE_COLORS[0]} to {TILE_COLORS[-1]}, "
                f"got {self.colors!r}"
            )
        for name in ("x", "y", "width", "length", "heading"):
            value = getattr(self, name)
            if not math.isfinite(value):
                raise MbnInputError(f"tile {name} must be finite, got {value!r}")
        if self.width <= 0 or self.length <= 0:
            raise MbnInputError(
                f"tile width and length must be > 0, got {self.width!r}, {self.length!r}"
            )

    def corners(self) -> np.ndarray:
        """The 4 corners ``(4, 2)`` of the strip, counter-clockwise."""
        c, s = math.cos(self.heading), math.sin(self.heading)
        along = np.array([c, s]) * self.length / 2
        across = np.array([-s, c]) * self.width / 2
        centre = np.array([self.x, self.y])
        return np.stack(
            [
                centre - along - across,
                centre + along - across,
                centre + along + across,
                centre - along + across,
            ]
        )


@dataclass(frozen=True)
class Maze:
    """A world for the robot: walls, tiles, start poses.

    Attributes:
        name: a short name (the built-in name, or the file's stem).
        walls: ``(K, 4)`` solid rectangles ``(xmin, xmax, ymin, ymax)``, metres.
        bounds: ``(xmin, xmax, ymin, ymax)`` of the world.
        outside_is_wall: whether everything outside ``bounds`` is solid.
        tiles: floor tiles.
        starts: ``(S, 3)`` start poses ``(x, y, theta)``.
        grid: for grid mazes, the ``(R, C)`` array of characters, first row north; its
            south-west corner is ``(bounds[0], bounds[2])`` (``(0, 0)`` for ``.maze`` files).
        cell: the side of a grid's square cells (metres); ``None`` without a grid, and for a
            grid whose columns and rows are not all one width (then ``edges`` has them).
        source: where the maze came from (a path, or ``"builtin"``).
        edges: for a grid whose columns and rows are not all one width (``cell`` is None), the
            ``x`` borders of its columns ``(C + 1,)`` and the ``y`` borders of its rows
            ``(R + 1,)``, increasing from ``bounds[0]`` and ``bounds[2]`` (row ``r`` spans
            ``[y[R - 1 - r], y[R - r]]``); ``None`` otherwise (:meth:`grid_edges` gives both
            kinds).
    """

    name: str
    walls: np.ndarray
    bounds: tuple[float, float, float, float]
    outside_is_wall: bool = True
    tiles: tuple[Tile, ...] = ()
    starts: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    grid: np.ndarray | None = None
    cell: float | None = None
    source: str = ""
    edges: tuple[np.ndarray, np.ndarray] | None = None

    def __post_init__(self) -> None:
        walls = np.asarray(self.walls, dtype=np.float64).reshape(-1, 4)
        starts = np.asarray(self.starts, dtype=np.float64).reshape(-1, 3)
        object.__setattr__(self, "walls", walls)
        object.__setattr__(self, "starts", starts)
        object.__setattr__(self, "bounds", tuple(float(b) for b in self.bounds))
        object.__setattr__(self, "tiles", tuple(self.tiles))
        if not (np.all(np.isfinite(walls)) and np.all(np.isfinite(starts))):
            raise MbnInputError(f"maze {self.name!r}: walls and starts must be finite")
        if np.any(walls[:, 1] <= walls[:, 0]) or np.any(walls[:, 3] <= walls[:, 2]):
            raise MbnInputError(f"maze {self.name!r}: every wall needs xmin < xmax and ymin < ymax")
        x0, x1, y0, y1 = self.bounds
        if not (x0 < x1 and y0 < y1):
            raise MbnInputError(f"maze {self.name!r}: empty bounds {self.bounds}")
        if self.edges is not None:
            xe, ye = (np.asarray(e, dtype=np.float64) for e in self.edges)
            object.__setattr__(self, "edges", (xe, ye))
            rows, cols = np.shape(self.grid) if self.grid is not None else (-1, -1)
            if (
                self.cell is not None
                or xe.shape != (cols + 1,)
                or ye.shape != (rows + 1,)
                or not (np.all(np.diff(xe) > 0) and np.all(np.diff(ye) > 0))
            ):
                raise MbnInputError(
                    f"maze {self.name!r}: edges must be the increasing borders of its grid's "
                    "columns and rows (and cell None)"
                )

    def grid_edges(self) -> tuple[np.ndarray, np.ndarray]:
        """The ``x`` borders of a grid maze's columns ``(C + 1,)`` and the ``y`` borders of its
        rows ``(R + 1,)`` (increasing; row ``r`` spans ``[y[R - 1 - r], y[R - r]]``): ``edges``,
        or ``cell`` steps from the south-west corner of ``bounds``."""
        if self.grid is None:
            raise MbnInputError(f"maze {self.name!r} has no grid")
        if self.edges is not None:
            return self.edges
        if self.cell is None:
            raise MbnInputError(f"maze {self.name!r}: a grid needs cell or edges")
        rows, cols = np.shape(self.grid)
        x0, _, y0, _ = self.bounds
        return x0 + np.arange(cols + 1) * self.cell, y0 + np.arange(rows + 1) * self.cell

    def is_free(self, x: float, y: float) -> bool:
        """Whether the point ``(x, y)`` lies in free space (on a wall's edge counts as free)."""
        x0, x1, y0, y1 = self.bounds
        if self.outside_is_wall and not (x0 <= x <= x1 and y0 <= y <= y1):
            return False
        w = self.walls
        inside = (w[:, 0] < x) & (x < w[:, 1]) & (w[:, 2] < y) & (y < w[:, 3])
        return not bool(np.any(inside))

    def solid_rects(self) -> np.ndarray:
        """The walls plus, when outside is solid, four rectangles framing ``bounds`` (1 m thick):
        every solid region as ``(K', 4)`` rectangles, e.g. for exact ray casting."""
        if not self.outside_is_wall:
            return self.walls
        x0, x1, y0, y1 = self.bounds
        t = 1.0
        frame = np.array(
            [
                [x0 - t, x1 + t, y0 - t, y0],
                [x0 - t, x1 + t, y1, y1 + t],
                [x0 - t, x0, y0, y1],
                [x1, x1 + t, y0, y1],
            ]
        )
        return np.concatenate([self.walls, frame], axis=0)


def merge_grid(solid: np.ndarray, x_edges: np.ndarray, y_edges: np.ndarray) -> np.ndarray:
    """Solid cells of a rectilinear grid as few rectangles ``(K, 4)``.

    ``solid`` is ``(R, C)`` with its first row north; column ``c`` spans
    ``[x_edges[c], x_edges[c + 1]]`` and row ``r`` spans ``[y_edges[R - 1 - r], y_edges[R - r]]``
    (``x_edges`` and ``y_edges`` increasing, of lengths ``C + 1`` and ``R + 1``). Horizontal runs of
    solid cells in each row are merged with identical runs below them; the rectangles come sorted
    from north to south, then west to east.
    """
    solid = np.asarray(solid, dtype=bool)
    rows, cols = solid.shape
    xe = np.asarray(x_edges, dtype=np.float64)
    ye = np.asarray(y_edges, dtype=np.float64)
    if xe.shape != (cols + 1,) or ye.shape != (rows + 1,):
        raise MbnInputError(
            f"merge_grid: a ({rows}, {cols}) grid needs {cols + 1} x edges and {rows + 1} y edges,"
            f" got {xe.size} and {ye.size}"
        )
    open_runs: dict[tuple[int, int], list[int]] = {}  # (c0, c1) -> [top row, bottom row]
    rects: list[tuple[int, int, int, int]] = []
    for r in range(rows):
        runs: list[tuple[int, int]] = []
        c = 0
        while c < cols:
            if solid[r, c]:
                c0 = c
                while c < cols and solid[r, c]:
                    c += 1
                runs.append((c0, c))
            else:
                c += 1
        still = {}
        for run in runs:
            if run in open_runs:
                top, _ = open_runs.pop(run)
                still[run] = [top, r]
            else:
                still[run] = [r, r]
        for run, (top, bottom) in open_runs.items():
            rects.append((run[0], run[1], top, bottom))
        open_runs = still
    for run, (top, bottom) in open_runs.items():
        rects.append((run[0], run[1], top, bottom))
    out = [
        (xe[c0], xe[c1], ye[rows - 1 - bottom], ye[rows - top])
        for c0, c1, top, bottom in sorted(rects, key=lambda q: (q[2], q[0]))
    ]
    return np.array(out, dtype=np.float64).reshape(-1, 4)


def merge_cells(
    solid: np.ndarray,
    cell: float,
    cell_y: float | None = None,
    origin: tuple[float, float] = (0.0, 0.0),
) -> np.ndarray:
    """Solid cells of a grid ``(R, C)`` (first row north, south-west corner at ``origin``) as few
    rectangles ``(K, 4)``: horizontal runs in each row, merged with identical runs below them.

    Cells are ``cell`` wide and ``cell_y`` tall (default: square cells, ``cell_y = cell``).
    """
    solid = np.asarray(solid, dtype=bool)
    rows, cols = solid.shape
    dy = cell if cell_y is None else cell_y
    x_edges = np.arange(cols + 1) * cell
    y_edges = np.arange(rows + 1) * dy
    if origin[0] != 0.0:
        x_edges = origin[0] + x_edges
    if origin[1] != 0.0:
        y_edges = origin[1] + y_edges
    return merge_grid(solid, x_edges, y_edges)
