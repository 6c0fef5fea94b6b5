"""Fast exact sensing and collision for batches of robots in batches of mazes.

A maze is compiled once (:func:`compile_mazes`) into a uniform occupancy lattice of square cells of
side ``g`` whose lines carry every wall edge, so that the lattice represents the walls *exactly*:
the maze's own cell for grid mazes, otherwise the largest ``g`` that divides every wall coordinate
(0.2 m for the Stage reference arena). Rays are then marched cell by cell (Amanatides & Woo's
DDA) and a reading is the exact distance to the first solid cell's face.

Spatial culling: for every cell the occupancy of the ``(2W+1)^2`` cells around it, W = the cells a
ray reaches (5 m plus the sonar ring's radius), is packed into a few 32-bit words. A robot step
gathers its cell's words once; the march then tests bits in registers. The cost of a robot step is
therefore independent of the maze's size: a 30 x 30 maze costs what a crossroad costs.

Worlds that are not grids (walls on a fine step or on none, far-apart walls, huge extents) would
make that lattice enormous; :func:`uses_lattice` sends them to the *segment path* instead: a
coarse uniform grid of culling cells, each listing the wall segments a ray from a robot in it can
reach and the wall rectangles its body can touch, cast and tested exactly (the formulas of
:mod:`mbn.world.geometry`). Its memory grows with the walls, not with the extent or a lattice.

Everything here is pure JAX over a flat batch of robots; each robot carries the index of its maze.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from functools import partial, reduce
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from mbn.errors import MbnInputError
from mbn.host import put
from mbn.world.geometry import rect_segments
from mbn.world.mazes.model import Maze
from mbn.world.robot import BODY, SONAR_MAX_RANGE, SONAR_POSES

__all__ = [
    "BASE_BLOBS",
    "CAMERA_POSITION",
    "LATTICE_MAX_BYTES",
    "LATTICE_MAX_WORDS",
    "MIN_LATTICE_CELL",
    "SEGMENT_MAX_CELLS",
    "SEGMENT_MIN_CELL",
    "CameraConfig",
    "CameraReading",
    "World",
    "cast",
    "cast_along",
    "collides_cells",
    "compile_mazes",
    "lattice_cell",
    "march_steps",
    "maze_constants",
    "see_tiles",
    "tile_under",
    "uses_lattice",
    "window_words",
]

#: Smallest lattice cell accepted when rasterising a maze given by rectangles (metres); a maze
#: whose wall coordinates have no common divisor this large cannot be compiled.
MIN_LATTICE_CELL = 0.05
#: Lattice budget: a world takes the lattice path when its cells' windows need at most this many
#: 32-bit words (cells of about 0.171 m or more) ...
LATTICE_MAX_WORDS = 128
#: ... and its packed window table at most this many bytes; otherwise the segment path.
LATTICE_MAX_BYTES = 32 * 2**20
#: Segment path: culling cells per maze at most (the cell grows with the extent) ...
SEGMENT_MAX_CELLS = 65_536
#: ... and at least this side (metres); grid mazes use their own cell.
SEGMENT_MIN_CELL = 1.0
#: Radius around the pose that holds every sonar origin and the body (metres).
_RING_RADIUS = float(
    max(np.hypot(SONAR_POSES[:, 0], SONAR_POSES[:, 1]).max(), np.hypot(*BODY.T).max())
)
_BODY_RADIUS = float(np.hypot(*BODY.T).max())
#: The camera sits at the middle of the body (robot frame, metres).
CAMERA_POSITION = (float(BODY[:, 0].mean()), 0.0)
#: Samples across a tile's width at which the camera tests visibility (fractions of the width).
_TILE_SAMPLES = np.array([-0.4, -0.15, 0.15, 0.4])
#: The blob slots of a tile in the camera's reading of mazes whose tiles have at most this many
#: colours (:attr:`World.n_blobs`).
BASE_BLOBS = 3


@dataclass(frozen=True)
class CameraConfig:
    """The blob-finding camera: field of view (degrees) and range (metres).

    Stage's blobfinder defaults to 60 degrees and 12 m; ``mbn`` keeps the 60 degrees and uses 3 m,
    because a floor strip 0.3 m long seen from a camera 0.3 m above the floor spans less than two
    pixels of Stage's 80 x 60 image beyond about 3 m (``docs/world.md``).
    """

    fov_deg: float = 60.0
    range: float = 3.0

    def __post_init__(self) -> None:
        if not (0.0 < self.fov_deg <= 180.0):
            raise MbnInputError(f"camera fov_deg must be in (0, 180], got {self.fov_deg!r}")
        if not (0.0 < self.range <= SONAR_MAX_RANGE):
            raise MbnInputError(
                f"camera range must be in (0, {SONAR_MAX_RANGE}] m, got {self.range!r}"
            )


@partial(
    jax.tree_util.register_dataclass,
    data_fields=[
        "origin",
        "cell",
        "shape",
        "half",
        "offset",
        "windows",
        "tiles",
        "tile_colors",
        "outside_is_wall",
        "segments",
        "seg_start",
        "seg_count",
        "seg_flat",
        "rects",
        "rect_start",
        "rect_count",
        "rect_flat",
        "row_solid",
        "grid_edges",
        "grid_shape",
        "grid_offset",
    ],
    meta_fields=[
        "n_words",
        "n_march",
        "n_body",
        "mode",
        "n_seg",
        "n_rect",
        "min_cell",
        "n_grid_rows",
        "n_blobs",
    ],
)
@dataclass(frozen=True)
class World:
    """Compiled mazes (a pytree of arrays with three static sizes; index a maze by its position in
    the list compiled).

    Per maze ``m``: lattice origin ``origin[m]`` (2,), cell ``cell[m]``, size
    ``shape[m] = (nx, ny)``, window half-width ``half[m]`` (cells), first row of its cells in
    ``windows``: ``offset[m]``.
    ``windows[k]`` packs the window of cell k (``nx * ny`` rows per maze, x-major, then one row for
    "outside the lattice"). Tiles: ``tiles[m, t] = (x, y, cos h, sin h, width, length)``,
    ``tile_colors[m, t]`` (0 = padding).

    ``mode`` is ``"lattice"`` or ``"segments"`` (:func:`uses_lattice`). On the segment path
    ``origin``, ``cell``, ``shape`` and ``offset`` describe each maze's grid of culling cells
    (``half`` is 0 and ``windows`` a placeholder); row ``r`` (same layout as the lattice's rows)
    lists the wall segments ``segments[seg_flat[seg_start[r] : seg_start[r] + seg_count[r]]]``
    (``(x1, y1, x2, y2)``) that a ray from a robot in that cell can reach, and likewise the wall
    rectangles ``rects`` (``(xmin, xmax, ymin, ymax)``) its body can touch; at most ``n_seg`` and
    ``n_rect`` per row. ``row_solid[r]``: the row is the outside of a walled maze (solid).
    On the lattice path these arrays are placeholders.

    ``min_cell`` (static): the smallest lattice cell (0 on the segment path): a ray of length
    ``r`` crosses at most ``2 (ceil(r / min_cell) + 1)`` cells (:func:`march_steps`).

    Junction judging (:mod:`mbn.world.stats`) indexes a grid maze of square cells by the cells
    above (its lattice or culling cells are its grid cells). A grid whose columns and rows are not
    all one width (:attr:`Maze.edges`) has its own: ``grid_edges[m]`` ``(2, E)`` its column (x)
    and row (y) borders, padded with +inf; ``grid_shape[m]`` its ``(columns, rows)`` (0, 0 for
    other mazes); ``grid_offset[m]`` the junction-table row of its first cell, after the
    ``n_rows`` rows above; ``n_grid_rows`` (static) the cells of all such grids. Without such a
    maze the three arrays are None and ``n_grid_rows`` is 0.

    ``n_blobs`` (static): the blobs a tile can show in these mazes, :data:`BASE_BLOBS` (3) or,
    when some tile has more colours, the most colours of any tile: the last axis of the camera's
    :attr:`CameraReading.visible` and ``bearing``, and the cap of a false blob
    (:func:`mbn.world.senses.camera_noise`). Mazes whose tiles have at most 3 colours compile
    the camera they always did (:func:`see_tiles`).
    """

    origin: Array
    cell: Array
    shape: Array
    half: Array
    offset: Array
    windows: Array
    tiles: Array
    tile_colors: Array
    outside_is_wall: Array
    segments: Array
    seg_start: Array
    seg_count: Array
    seg_flat: Array
    rects: Array
    rect_start: Array
    rect_count: Array
    rect_flat: Array
    row_solid: Array
    n_words: int
    n_march: int
    n_body: int
    mode: str = "lattice"
    n_seg: int = 1
    n_rect: int = 1
    min_cell: float = 0.0
    grid_edges: Array | None = None
    grid_shape: Array | None = None
    grid_offset: Array | None = None
    n_grid_rows: int = 0
    n_blobs: int = BASE_BLOBS

    @property
    def n_rows(self) -> int:
        """Rows of the per-cell tables (every maze's cells plus one "outside" row each)."""
        if self.mode == "segments":
            return int(self.seg_start.shape[0])
        return int(self.windows.shape[0])

    @property
    def n_junction_rows(self) -> int:
        """Rows of the junction tables (:func:`mbn.world.stats.junction_arrays`): the rows above,
        then the cells of the grids with columns and rows of several widths."""
        return self.n_rows + self.n_grid_rows


def _rational_gcd(values: list[float]) -> float | None:
    g = Fraction(0)
    for v in values:
        f = Fraction(v).limit_denominator(100_000)
        if abs(float(f) - v) > 1e-9 * max(1.0, abs(v)):
            return None
        a, b = g.numerator * f.denominator, f.numerator * g.denominator
        den = g.denominator * f.denominator
        g = Fraction(math.gcd(a, b), den)
    return float(g) if g > 0 else None


def lattice_cell(maze: Maze) -> tuple[float, tuple[float, float]]:
    """The lattice ``(cell, origin)`` that represents ``maze``'s walls exactly.

    Grid mazes of square cells use their own cell and its south-west corner, the lower-left
    corner of their bounds ((0, 0) for ``.maze`` files); other mazes the largest cell that divides
    every wall coordinate measured from that corner (at most 2 m).
    """
    x0, _, y0, _ = maze.bounds
    if maze.grid is not None and maze.cell is not None:
        return float(maze.cell), (x0, y0)
    vals = [abs(v - x0) for v in maze.walls[:, :2].ravel()] + [
        abs(v - y0) for v in maze.walls[:, 2:].ravel()
    ]
    if maze.outside_is_wall:
        vals += [maze.bounds[1] - x0, maze.bounds[3] - y0]
    vals = [v for v in vals if v > 1e-12]
    g = _rational_gcd(vals) if vals else 1.0
    if g is None or g < MIN_LATTICE_CELL - 1e-12:
        raise MbnInputError(
            f"maze {maze.name!r}: wall coordinates share no lattice of cell >= "
            f"{MIN_LATTICE_CELL} m (put wall edges on multiples of a common step, e.g. 0.05 m)"
        )
    while g > 2.0 + 1e-12:  # keep windows informative for very coarse mazes
        g /= 2.0
    return g, (x0, y0)


def _lattice_size(maze: Maze, g: float, origin: tuple[float, float]) -> tuple[int, int]:
    """Lattice cells ``(nx, ny)`` over the maze's bounds (without margin)."""
    x0, x1, y0, y1 = maze.bounds
    nx_in = round((x1 - origin[0]) / g) if maze.outside_is_wall else math.ceil((x1 - x0) / g)
    ny_in = round((y1 - origin[1]) / g) if maze.outside_is_wall else math.ceil((y1 - y0) / g)
    return nx_in, ny_in


def _window_half(g: float) -> int:
    return math.ceil((SONAR_MAX_RANGE + _RING_RADIUS) / g)


def uses_lattice(mazes: list[Maze] | tuple[Maze, ...]) -> bool:
    """Whether :func:`compile_mazes` puts these mazes on the exact lattice (else the segment path).

    Every maze must have a lattice (:func:`lattice_cell`; a grid maze always has its own), the
    windows must fit :data:`LATTICE_MAX_WORDS` words and the window table
    :data:`LATTICE_MAX_BYTES` bytes. Lists of grid mazes always do.
    """
    cells, words = 0, 1
    for maze in mazes:
        try:
            g, origin = lattice_cell(maze)
        except MbnInputError:
            return False
        half = _window_half(g)
        words = max(words, math.ceil((2 * half + 1) ** 2 / 32))
        if words > LATTICE_MAX_WORDS:
            return False
        nx, ny = _lattice_size(maze, g, origin)
        margin = 0 if maze.outside_is_wall else half
        cells += (nx + 2 * margin) * (ny + 2 * margin) + 1
        if cells * words * 4 > LATTICE_MAX_BYTES and not _all_grids(mazes):
            return False
    return True


def _all_grids(mazes: list[Maze] | tuple[Maze, ...]) -> bool:
    return all(m.grid is not None and m.cell is not None for m in mazes)


def _occupancy(maze: Maze, g: float, origin: tuple[float, float], margin: int) -> np.ndarray:
    """Solid cells ``(nx, ny)`` (x index first) of the lattice over the bounds plus ``margin``
    cells on every side."""
    nx_in, ny_in = _lattice_size(maze, g, origin)
    nx, ny = nx_in + 2 * margin, ny_in + 2 * margin
    occ = np.full((nx, ny), bool(maze.outside_is_wall))
    occ[margin : margin + nx_in, margin : margin + ny_in] = False
    for xa, xb, ya, yb in maze.walls:
        ia = round((xa - origin[0]) / g) + margin
        ib = round((xb - origin[0]) / g) + margin
        ja = round((ya - origin[1]) / g) + margin
        jb = round((yb - origin[1]) / g) + margin
        occ[max(ia, 0) : max(ib, 0), max(ja, 0) : max(jb, 0)] = True
    return occ


def _pack_windows(occ: np.ndarray, half: int, n_words: int, outside: bool) -> np.ndarray:
    """``(nx * ny + 1, n_words)`` uint32: bit ``(di + half) * (2 half + 1) + (dj + half)`` of the
    window of cell ``(i, j)`` is the occupancy of cell ``(i + di, j + dj)``; the last row is the
    window of a cell outside the lattice."""
    nx, ny = occ.shape
    side = 2 * half + 1
    pad = np.full((nx + 2 * half, ny + 2 * half), outside)
    pad[half : half + nx, half : half + ny] = occ
    view = np.lib.stride_tricks.sliding_window_view(pad, (side, side))  # (nx, ny, side, side)
    weights = np.uint64(1) << np.arange(32, dtype=np.uint64)
    out = np.empty((nx * ny + 1, n_words), dtype=np.uint32)
    # a few x-columns of cells at a time, so that the unpacked bits stay small (about 64 MiB)
    step = max(1, (1 << 23) // max(1, ny * n_words * 32))
    for i in range(0, nx, step):
        cols = view[i : i + step]
        bits = np.zeros((cols.shape[0] * ny, n_words * 32), dtype=np.uint64)
        bits[:, : side * side] = cols.reshape(-1, side * side)
        out[i * ny : (i + cols.shape[0]) * ny] = (bits.reshape(-1, n_words, 32) * weights).sum(-1)
    last = np.zeros((1, n_words * 32), dtype=np.uint64)
    last[:, : side * side] = outside
    out[-1] = (last.reshape(-1, n_words, 32) * weights).sum(-1)[0]
    return out


def compile_mazes(mazes: list[Maze] | tuple[Maze, ...]) -> World:
    """Compile mazes for :func:`cast`, :func:`collides_cells` and the camera (NumPy, once): on the
    exact lattice when :func:`uses_lattice`, else on the segment path."""
    if not mazes:
        raise MbnInputError("compile_mazes needs at least one maze")
    if not uses_lattice(mazes):
        return _compile_segments(mazes)
    lattices = [lattice_cell(m) for m in mazes]
    halves = [_window_half(g) for g, _ in lattices]
    n_words = max(math.ceil((2 * h + 1) ** 2 / 32) for h in halves)
    n_march = max(2 * (math.ceil(SONAR_MAX_RANGE / g) + 1) for g, _ in lattices)
    n_body = max(math.ceil(2 * _BODY_RADIUS / g) + 1 for g, _ in lattices)
    origins, shapes, offsets, tables = [], [], [], []
    offset = 0
    for maze, (g, origin), half in zip(mazes, lattices, halves, strict=True):
        margin = 0 if maze.outside_is_wall else half
        occ = _occupancy(maze, g, origin, margin)
        origins.append((origin[0] - margin * g, origin[1] - margin * g))
        shapes.append(occ.shape)
        offsets.append(offset)
        table = _pack_windows(occ, half, n_words, bool(maze.outside_is_wall))
        tables.append(table)
        offset += table.shape[0]
    # float32, or float64 under jax_enable_x64; the arrays are made in NumPy and put on the
    # device as they are (no eager operation to compile)
    dtype = np.dtype(jnp.zeros(()).dtype)
    tiles, colors = _tile_arrays(mazes)
    return World(
        origin=put(origins, dtype),
        cell=put([g for g, _ in lattices], dtype),
        shape=put(shapes, np.int32),
        half=put(halves, np.int32),
        offset=put(offsets, np.int32),
        windows=put(np.concatenate(tables, axis=0)),
        tiles=put(tiles, dtype),
        tile_colors=put(colors),
        outside_is_wall=put([m.outside_is_wall for m in mazes], bool),
        segments=put(np.zeros((1, 4)), dtype),
        seg_start=put(np.zeros((1,)), np.int32),
        seg_count=put(np.zeros((1,)), np.int32),
        seg_flat=put(np.zeros((1,)), np.int32),
        rects=put(np.zeros((1, 4)), dtype),
        rect_start=put(np.zeros((1,)), np.int32),
        rect_count=put(np.zeros((1,)), np.int32),
        rect_flat=put(np.zeros((1,)), np.int32),
        row_solid=put(np.zeros((1,)), bool),
        n_words=n_words,
        n_march=n_march,
        n_body=n_body,
        min_cell=float(min(g for g, _ in lattices)),
        n_blobs=_blob_slots(mazes),
        **_edge_grids(mazes, offset, dtype),
    )


def _edge_grids(mazes: list[Maze] | tuple[Maze, ...], n_rows: int, dtype: Any) -> dict[str, Any]:
    """The :class:`World` fields of the grids whose columns and rows are not all one width (none
    when no maze has one)."""
    grids = [m.grid_edges() if m.grid is not None and m.cell is None else None for m in mazes]
    if all(g is None for g in grids):
        return {}
    n_edges = max(max(len(g[0]), len(g[1])) for g in grids if g is not None)
    edges = np.full((len(mazes), 2, n_edges), np.inf)
    shape = np.zeros((len(mazes), 2), np.int64)
    offset = np.zeros(len(mazes), np.int64)
    row = n_rows
    for k, g in enumerate(grids):
        if g is None:
            continue
        edges[k, 0, : len(g[0])] = g[0]
        edges[k, 1, : len(g[1])] = g[1]
        shape[k] = (len(g[0]) - 1, len(g[1]) - 1)
        offset[k] = row
        row += int(shape[k, 0] * shape[k, 1])
    return {
        "grid_edges": put(edges, np.dtype(dtype)),
        "grid_shape": put(shape, np.int32),
        "grid_offset": put(offset, np.int32),
        "n_grid_rows": row - n_rows,
    }


def _blob_slots(mazes: list[Maze] | tuple[Maze, ...]) -> int:
    """:attr:`World.n_blobs`: 3, or the most colours of any tile when more."""
    return max([BASE_BLOBS, *(t.colors for m in mazes for t in m.tiles)])


def _tile_arrays(mazes: list[Maze] | tuple[Maze, ...]) -> tuple[np.ndarray, np.ndarray]:
    n_tiles = max(1, max(len(m.tiles) for m in mazes))
    tiles = np.zeros((len(mazes), n_tiles, 6))
    colors = np.zeros((len(mazes), n_tiles), dtype=np.int32)
    for k, maze in enumerate(mazes):
        for t, tile in enumerate(maze.tiles):
            h = tile.heading
            tiles[k, t] = (tile.x, tile.y, math.cos(h), math.sin(h), tile.width, tile.length)
            colors[k, t] = tile.colors
    return tiles, colors


# ---------------------------------------------------------------------------------------------
# the segment path: culling cells listing the segments and rectangles within reach


def _culling_grid(maze: Maze, reach: float) -> tuple[float, tuple[float, float], tuple[int, int]]:
    """``(cell, origin, (nx, ny))`` of a maze's culling cells: a grid maze's own cells; otherwise
    square cells of at least :data:`SEGMENT_MIN_CELL` over the bounds (grown by ``reach`` when the
    outside is open), at most :data:`SEGMENT_MAX_CELLS` of them."""
    x0, x1, y0, y1 = maze.bounds
    if maze.grid is not None and maze.cell is not None:
        c = float(maze.cell)
        return c, (x0, y0), (max(1, round((x1 - x0) / c)), max(1, round((y1 - y0) / c)))
    if not maze.outside_is_wall:
        x0, x1, y0, y1 = x0 - reach, x1 + reach, y0 - reach, y1 + reach
    w, h = x1 - x0, y1 - y0
    c = max(SEGMENT_MIN_CELL, math.sqrt(w * h / SEGMENT_MAX_CELLS))
    while math.ceil(w / c) * math.ceil(h / c) > SEGMENT_MAX_CELLS:
        c *= 1.05
    return c, (x0, y0), (max(1, math.ceil(w / c)), max(1, math.ceil(h / c)))


def _cell_lists(
    boxes: np.ndarray,
    reach: float,
    c: float,
    origin: tuple[float, float],
    shape: tuple[int, int],
) -> tuple[np.ndarray, np.ndarray]:
    """For each culling cell (rows ``i * ny + j``), the items whose bounding box
    ``boxes (N, 4) = (xmin, xmax, ymin, ymax)`` lies within ``reach`` of the cell: ``(rows, items)``
    pairs sorted by row."""
    nx, ny = shape
    ox, oy = origin
    rows: list[np.ndarray] = []
    items: list[np.ndarray] = []
    for n, (bx0, bx1, by0, by1) in enumerate(boxes):
        i0 = max(0, math.floor((bx0 - reach - ox) / c))
        i1 = min(nx - 1, math.floor((bx1 + reach - ox) / c))
        j0 = max(0, math.floor((by0 - reach - oy) / c))
        j1 = min(ny - 1, math.floor((by1 + reach - oy) / c))
        if i1 < i0 or j1 < j0:
            continue
        i = np.arange(i0, i1 + 1)[:, None]
        j = np.arange(j0, j1 + 1)[None, :]
        gx = np.maximum(0.0, np.maximum(ox + i * c - bx1, bx0 - (ox + (i + 1) * c)))
        gy = np.maximum(0.0, np.maximum(oy + j * c - by1, by0 - (oy + (j + 1) * c)))
        near = gx**2 + gy**2 <= reach**2
        ii, jj = np.nonzero(near)
        rows.append((ii + i0) * ny + (jj + j0))
        items.append(np.full(len(ii), n))
    if not rows:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    r, it = np.concatenate(rows), np.concatenate(items)
    order = np.argsort(r, kind="stable")
    return r[order], it[order]


def _csr(
    pairs: list[tuple[np.ndarray, np.ndarray]], n_rows: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """``(start, count, flat, k_max)`` from ``(global row, global item)`` pairs sorted by row;
    ``flat`` is padded by ``k_max`` so that ``flat[start + arange(k_max)]`` stays in bounds."""
    rows = np.concatenate([p[0] for p in pairs]) if pairs else np.zeros(0, np.int64)
    items = np.concatenate([p[1] for p in pairs]) if pairs else np.zeros(0, np.int64)
    count = np.bincount(rows, minlength=n_rows).astype(np.int32)
    start = (np.cumsum(count) - count).astype(np.int32)
    k_max = max(1, int(count.max()) if len(count) else 1)
    flat = np.concatenate([items, np.zeros(k_max, np.int64)]).astype(np.int32)
    return start, count, flat, k_max


def _compile_segments(mazes: list[Maze] | tuple[Maze, ...]) -> World:
    ray_reach = SONAR_MAX_RANGE + _RING_RADIUS
    tol = 1e-6
    origins, cells, shapes, offsets = [], [], [], []
    segs, rects = [], []
    seg_pairs: list[tuple[np.ndarray, np.ndarray]] = []
    rect_pairs: list[tuple[np.ndarray, np.ndarray]] = []
    solid: list[np.ndarray] = []
    row0 = n_seg0 = n_rect0 = 0
    for maze in mazes:
        c, origin, shape = _culling_grid(maze, ray_reach + tol)
        scale = max(1.0, *(abs(v) for v in maze.bounds))
        reach_tol = tol + 1e-9 * scale
        r = np.asarray(maze.solid_rects(), dtype=np.float64).reshape(-1, 4)
        sg = rect_segments(r)
        seg_boxes = np.stack(
            [
                np.minimum(sg[:, 0], sg[:, 2]),
                np.maximum(sg[:, 0], sg[:, 2]),
                np.minimum(sg[:, 1], sg[:, 3]),
                np.maximum(sg[:, 1], sg[:, 3]),
            ],
            -1,
        )
        sr, si = _cell_lists(seg_boxes, ray_reach + reach_tol, c, origin, shape)
        rr, ri = _cell_lists(r, _BODY_RADIUS + reach_tol, c, origin, shape)
        seg_pairs.append((sr + row0, si + n_seg0))
        rect_pairs.append((rr + row0, ri + n_rect0))
        n_cells = shape[0] * shape[1]
        row_solid = np.zeros(n_cells + 1, bool)
        row_solid[-1] = bool(maze.outside_is_wall)
        solid.append(row_solid)
        origins.append(origin)
        cells.append(c)
        shapes.append(shape)
        offsets.append(row0)
        segs.append(sg)
        rects.append(r)
        row0 += n_cells + 1
        n_seg0 += len(sg)
        n_rect0 += len(r)
    seg_start, seg_count, seg_flat, n_seg = _csr(seg_pairs, row0)
    rect_start, rect_count, rect_flat, n_rect = _csr(rect_pairs, row0)
    dtype = jnp.zeros(()).dtype
    tiles, colors = _tile_arrays(mazes)
    return World(
        origin=jnp.asarray(np.array(origins), dtype),
        cell=jnp.asarray(np.array(cells), dtype),
        shape=jnp.asarray(np.array(shapes), jnp.int32),
        half=jnp.zeros(len(mazes), jnp.int32),
        offset=jnp.asarray(np.array(offsets), jnp.int32),
        windows=jnp.zeros((1, 1), jnp.uint32),
        tiles=jnp.asarray(tiles, dtype),
        tile_colors=put(colors),
        outside_is_wall=jnp.asarray(np.array([m.outside_is_wall for m in mazes])),
        segments=jnp.asarray(np.concatenate([*segs, np.zeros((1, 4))]), dtype),
        seg_start=jnp.asarray(seg_start),
        seg_count=jnp.asarray(seg_count),
        seg_flat=jnp.asarray(seg_flat),
        rects=jnp.asarray(np.concatenate([*rects, np.zeros((1, 4))]), dtype),
        rect_start=jnp.asarray(rect_start),
        rect_count=jnp.asarray(rect_count),
        rect_flat=jnp.asarray(rect_flat),
        row_solid=jnp.asarray(np.concatenate(solid)),
        n_words=1,
        n_march=0,
        n_body=0,
        mode="segments",
        n_seg=n_seg,
        n_rect=n_rect,
        n_blobs=_blob_slots(mazes),
        **_edge_grids(mazes, row0, dtype),
    )


class MazeConstants(NamedTuple):
    """Per-robot constants of its maze (gathered once per rollout): origin ``(..., 2)``, cell,
    lattice shape ``(..., 2)``, window half-width, window side, first table row."""

    origin: Array
    cell: Array
    shape: Array
    half: Array
    side: Array
    offset: Array


def maze_constants(world: World, maze_index: Array) -> MazeConstants:
    """The constants of each robot's maze, ``maze_index (...,)``."""
    half = world.half[maze_index]
    return MazeConstants(
        origin=world.origin[maze_index],
        cell=world.cell[maze_index],
        shape=world.shape[maze_index],
        half=half,
        side=2 * half + 1,
        offset=world.offset[maze_index],
    )


def _cell_of(mc: MazeConstants, x: Array, y: Array) -> tuple[Array, Array]:
    return (
        jnp.floor((x - mc.origin[..., 0]) / mc.cell).astype(jnp.int32),
        jnp.floor((y - mc.origin[..., 1]) / mc.cell).astype(jnp.int32),
    )


def window_words(world: World, mc: MazeConstants, x: Array, y: Array) -> tuple[Array, Array, Array]:
    """The packed window ``(..., n_words)`` of the cell holding ``(x, y)``, and that cell's
    lattice indices ``(i, j)``. On the segment path: the culling cell's table row ``(..., 1)``
    (int32) and the culling cell's indices."""
    i, j = _cell_of(mc, x, y)
    nx, ny = mc.shape[..., 0], mc.shape[..., 1]
    inside = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
    row = jnp.where(inside, mc.offset + i * ny + j, mc.offset + nx * ny)
    if world.mode == "segments":
        return row[..., None], i, j
    return world.windows[row], i, j


def _bit(words: Array, n_words: int, b: Array) -> Array:
    """Bit ``b (..., k)`` of each robot's window ``words (..., n_words)`` as bool."""
    w_index = b >> 5
    if n_words <= 8:
        w = jnp.broadcast_to(words[..., 0:1], b.shape)
        for k in range(1, n_words):
            w = jnp.where(w_index == k, words[..., k : k + 1], w)
    else:
        flat = jnp.broadcast_to(words[..., None, :], (*b.shape, n_words))
        w = jnp.take_along_axis(flat, w_index[..., None], axis=-1)[..., 0]
    return ((w >> (b & 31).astype(jnp.uint32)) & 1).astype(bool)


def cast(
    world: World,
    mc: MazeConstants,
    words: Array,
    ci: Array,
    cj: Array,
    ox: Array,
    oy: Array,
    angle: Array,
    max_range: float | Array = SONAR_MAX_RANGE,
    *,
    reach: float | None = None,
) -> Array:
    """Exact distance along rays to the first solid cell, capped at ``max_range``.

    ``words``, ``ci``, ``cj`` from :func:`window_words` for the robot (shape ``(B, ...)``);
    ray origins ``ox, oy`` and headings ``angle`` of shape ``(B, k)``, each origin within
    ``_RING_RADIUS`` of the robot's pose and in free space. ``reach`` (static, metres) marches
    only the lattice steps a ray of that length needs (:func:`march_steps`): a wall within
    ``reach`` reads exactly as without it, one beyond reads either its distance or
    ``max_range`` (the miss).
    """
    steps = None if reach is None else march_steps(world, reach)
    return cast_along(
        world, mc, words, ci, cj, ox, oy, jnp.cos(angle), jnp.sin(angle), max_range, steps=steps
    )


def march_steps(world: World, max_range: float) -> int:
    """Lattice steps a ray of length ``max_range`` needs (at most the world's ``n_march``, the
    sonars' range)."""
    if world.min_cell <= 0:
        return world.n_march
    return min(world.n_march, 2 * (math.ceil(max_range / world.min_cell) + 1))


def cast_along(
    world: World,
    mc: MazeConstants,
    words: Array,
    ci: Array,
    cj: Array,
    ox: Array,
    oy: Array,
    dx: Array,
    dy: Array,
    max_range: float | Array = SONAR_MAX_RANGE,
    *,
    steps: int | None = None,
) -> Array:
    """:func:`cast` along unit directions ``(dx, dy)`` instead of headings; ``steps`` (static)
    marches at most that many lattice steps (:func:`march_steps` of a shorter range than the
    sonars'; default the world's ``n_march``)."""
    if world.mode == "segments":
        return _cast_segments(world, words, ox, oy, dx, dy, max_range)
    cell = mc.cell[..., None]
    gx = (ox - mc.origin[..., 0:1]) / cell
    gy = (oy - mc.origin[..., 1:2]) / cell
    fi, fj = jnp.floor(gx), jnp.floor(gy)
    big = jnp.asarray(1e30, gx.dtype)
    adx, ady = jnp.abs(dx), jnp.abs(dy)
    inv_x = jnp.where(adx > 1e-12, cell / jnp.where(adx > 1e-12, adx, 1.0), big)
    inv_y = jnp.where(ady > 1e-12, cell / jnp.where(ady > 1e-12, ady, 1.0), big)
    tx = jnp.where(dx > 0, fi + 1.0 - gx, gx - fi) * inv_x
    ty = jnp.where(dy > 0, fj + 1.0 - gy, gy - fj) * inv_y
    half = mc.half[..., None]
    side = mc.side[..., None]
    li = fi.astype(jnp.int32) - ci[..., None] + half
    lj = fj.astype(jnp.int32) - cj[..., None] + half
    si = jnp.where(dx > 0, 1, -1)
    sj = jnp.where(dy > 0, 1, -1)
    dist = jnp.full(ox.shape, max_range, ox.dtype)
    done = jnp.zeros(ox.shape, bool)
    for _ in range(world.n_march if steps is None else min(steps, world.n_march)):
        step_x = tx < ty
        t = jnp.minimum(tx, ty)
        li = jnp.where(step_x, li + si, li)
        lj = jnp.where(step_x, lj, lj + sj)
        solid = _bit(words, world.n_words, li * side + lj)
        dist = jnp.where(solid & ~done, t, dist)
        done = done | solid
        tx = jnp.where(step_x, tx + inv_x, tx)
        ty = jnp.where(step_x, ty, ty + inv_y)
    return jnp.minimum(dist, max_range)


def _gather(
    start: Array, count: Array, flat: Array, table: Array, k: int, row: Array, dtype: Any
) -> tuple[Array, Array]:
    """The items ``(B, k, 4)`` listed for table rows ``row (B,)`` and which are real ``(B, k)``."""
    slot = jnp.arange(k)
    ids = flat[start[row][:, None] + slot]
    return table[ids].astype(dtype), slot < count[row][:, None]


def _cast_segments(
    world: World,
    words: Array,
    ox: Array,
    oy: Array,
    dx: Array,
    dy: Array,
    max_range: float | Array,
) -> Array:
    """:func:`cast` on the segment path: the exact caster of :func:`mbn.world.geometry.cast_rays`
    over the segments listed for each robot's culling cell (``words[:, 0]``: its row)."""
    row = words[:, 0]
    seg, valid = _gather(
        world.seg_start, world.seg_count, world.seg_flat, world.segments, world.n_seg, row, ox.dtype
    )
    dx, dy = dx[..., None], dy[..., None]  # (B, k, 1)
    px, py = seg[:, None, :, 0], seg[:, None, :, 1]  # (B, 1, S)
    ex, ey = seg[:, None, :, 2] - px, seg[:, None, :, 3] - py
    wx, wy = px - ox[..., None], py - oy[..., None]
    denom = dx * ey - dy * ex
    ok = (jnp.abs(denom) > 1e-12) & valid[:, None, :]
    safe = jnp.where(ok, denom, 1.0)
    t = (wx * ey - wy * ex) / safe
    s = (wx * dy - wy * dx) / safe
    hit = ok & (t >= 0.0) & (s >= 0.0) & (s <= 1.0)
    dist = jnp.min(jnp.where(hit, t, jnp.inf), axis=-1)
    dist = jnp.where(world.row_solid[row][:, None], 0.0, dist)
    return jnp.minimum(dist, max_range)


def _collides_rects(world: World, words: Array, pose: Array) -> Array:
    """:func:`collides_cells` on the segment path: the separating-axis test of
    :func:`mbn.world.geometry.collides` against the rectangles listed for the pose's culling cell;
    the outside of a walled maze is solid."""
    row = words[:, 0]
    r, valid = _gather(
        world.rect_start,
        world.rect_count,
        world.rect_flat,
        world.rects,
        world.n_rect,
        row,
        pose.dtype,
    )
    th = pose[:, 2:3]
    c, s = jnp.cos(th), jnp.sin(th)
    bx = jnp.asarray(BODY[:, 0], pose.dtype)
    by = jnp.asarray(BODY[:, 1], pose.dtype)
    px = pose[:, 0:1] + c * bx - s * by  # (B, 8)
    py = pose[:, 1:2] + s * bx + c * by
    sep = (jnp.max(px, -1)[:, None] <= r[..., 0]) | (jnp.min(px, -1)[:, None] >= r[..., 1])
    sep = sep | (jnp.max(py, -1)[:, None] <= r[..., 2]) | (jnp.min(py, -1)[:, None] >= r[..., 3])
    cx = jnp.stack([r[..., 0], r[..., 1], r[..., 1], r[..., 0]], -1)  # (B, K, 4) corners
    cy = jnp.stack([r[..., 2], r[..., 2], r[..., 3], r[..., 3]], -1)
    for a in range(len(_AXES)):
        ax, ay = float(_AXES[a, 0]), float(_AXES[a, 1])
        nx, ny = c * ax - s * ay, s * ax + c * ay  # (B, 1) world-frame normal
        proj_body = px * nx + py * ny  # (B, 8)
        bmin = jnp.min(proj_body, -1, keepdims=True)
        bmax = jnp.max(proj_body, -1, keepdims=True)
        proj = cx * nx[..., None] + cy * ny[..., None]
        sep = sep | (bmax <= jnp.min(proj, -1)) | (bmin >= jnp.max(proj, -1))
    return jnp.any(valid & ~sep, axis=-1) | world.row_solid[row]


# Body octagon projected on its own edge normals (robot frame): the separating axes of the SAT.
def _body_axes() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    edges = np.roll(BODY, -1, axis=0) - BODY
    normals = np.stack([-edges[:, 1], edges[:, 0]], -1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    unique: list[np.ndarray] = []
    for n in normals:
        if not any(abs(abs(float(n @ u)) - 1.0) < 1e-9 for u in unique):
            unique.append(n)
    axes = np.array(unique)
    proj = BODY @ axes.T  # (8, A)
    return axes, proj.min(0), proj.max(0)


_AXES, _AXES_MIN, _AXES_MAX = _body_axes()


def collides_cells(
    world: World, mc: MazeConstants, words: Array, ci: Array, cj: Array, pose: Array
) -> Array:
    """Whether the body at ``pose (B, 3)`` overlaps a solid cell (touching is not overlapping).

    ``words, ci, cj`` describe the window of the cell holding the pose. Separating-axis test of the
    octagon against each solid cell under the body's bounding square (``n_body`` cells a side):
    the two lattice axes and the octagon's edge normals. On the segment path: against the wall
    rectangles listed for the pose's culling cell.

    Written cell by cell and corner by corner on ``(B,)`` arrays, the batch along the fast axis:
    XLA fuses it into one loop over the robots, about 6 x faster on a CPU than the same arithmetic
    on ``(B, cells)`` and ``(B, 8)`` arrays, and the same booleans (``docs/speed.md``).
    """
    if world.mode == "segments":
        return _collides_rects(world, words, pose)
    n = world.n_body
    x, y, th = pose[..., 0], pose[..., 1], pose[..., 2]
    cell, half, side = mc.cell, mc.half, mc.side
    ox, oy = mc.origin[..., 0], mc.origin[..., 1]
    # first cell under the body's bounding square, relative to the pose's cell
    i0 = jnp.floor((x - _BODY_RADIUS - ox) / cell).astype(jnp.int32) - ci
    j0 = jnp.floor((y - _BODY_RADIUS - oy) / cell).astype(jnp.int32) - cj
    c, s = jnp.cos(th), jnp.sin(th)
    corners_x = [x + c * float(bx) - s * float(by) for bx, by in BODY]
    corners_y = [y + s * float(bx) + c * float(by) for bx, by in BODY]
    x_max, x_min = reduce(jnp.maximum, corners_x), reduce(jnp.minimum, corners_x)
    y_max, y_min = reduce(jnp.maximum, corners_y), reduce(jnp.minimum, corners_y)
    normals = []  # the octagon's edge normals in the world frame, and a cell's half extent on them
    for ax, ay in _AXES:
        nx, ny = c * float(ax) - s * float(ay), s * float(ax) + c * float(ay)
        normals.append((nx, ny, cell / 2 * (jnp.abs(nx) + jnp.abs(ny))))
    hit = jnp.zeros(x.shape, bool)
    for di in range(n):
        for dj in range(n):
            li, lj = i0 + di, j0 + dj  # relative to the pose's cell
            x0 = ox + (ci + li) * cell  # the cell's lower-left corner
            y0 = oy + (cj + lj) * cell
            solid = _bit(words, world.n_words, ((half + li) * side + half + lj)[..., None])[..., 0]
            sep = (x_max <= x0) | (x_min >= x0 + cell) | (y_max <= y0) | (y_min >= y0 + cell)
            cx, cy = x0 + cell / 2 - x, y0 + cell / 2 - y
            for a, (nx, ny, extent) in enumerate(normals):
                centre = cx * nx + cy * ny
                sep = sep | (centre - extent >= _AXES_MAX[a]) | (centre + extent <= _AXES_MIN[a])
            hit = hit | (solid & ~sep)
    return hit


class CameraReading(NamedTuple):
    """What the blob finder reports at one step.

    ``blobs``: the number of distinct colour blobs in view (each visible tile shows one blob per
    colour). ``nearest``: the number of colours (0 none, 1 to 6) of the nearest tile in view —
    the camera input of the program module. ``visible``: ``(..., T, N)`` which blobs of which
    tile are in view (``N`` = :attr:`World.n_blobs`: 3, or the most colours of any tile when
    more); ``bearing``: ``(..., T, N)`` each blob's bearing in the camera frame (radians,
    positive left; meaningful where visible).
    """

    blobs: Array
    nearest: Array
    visible: Array
    bearing: Array


def _blob_tables(n_blobs: int) -> tuple[np.ndarray, np.ndarray]:
    """The samples of a world with tiles of up to ``n_blobs`` (> 3) colours, by a tile's colours
    ``c`` (row ``c``, 0 padding): ``centre (n + 1, n)``, the fraction of the width of its extra
    samples, the centres of its ``c`` parts (tiles of 4 or more colours; 0 elsewhere), and
    ``part (n + 1, 4 + n)``, the blob each sample of :data:`_TILE_SAMPLES` and then each extra
    sample belongs to (-1: none). A tile of 1 to 3 colours has no extra samples and its four
    samples' parts are those of :func:`see_tiles`'s three-blob reading."""
    n, k = n_blobs, len(_TILE_SAMPLES)
    u = _TILE_SAMPLES
    centre = np.zeros((n + 1, n))
    part = np.full((n + 1, k + n), -1, np.int32)
    part[1, :k] = 0
    part[2, :k] = np.where(u < 0, 0, 1)
    part[3, :k] = np.where(u < -1 / 6, 0, np.where(u > 1 / 6, 2, 1))
    for c in range(BASE_BLOBS + 1, n + 1):
        part[c, :k] = np.minimum(np.floor((u + 0.5) * c), c - 1)
        centre[c, :c] = -0.5 + (np.arange(c) + 0.5) / c
        part[c, k : k + c] = np.arange(c)
    return centre, part


def see_tiles(
    world: World,
    mc: MazeConstants,
    maze_index: Array,
    words: Array,
    ci: Array,
    cj: Array,
    pose: Array,
    camera: CameraConfig,
) -> CameraReading:
    """The blob finder at ``pose (B, 3)``: a tile's blob is in view when one of its sample points
    (across the tile's width) is within the field of view and range and no wall lies between the
    camera and it. A tile of ``c`` colours is ``c`` equal parts side by side across its width,
    one blob each: a two-colour tile's halves, a three-colour tile's thirds.

    Samples: four across every tile's width (:data:`_TILE_SAMPLES`); in worlds with tiles of 4
    or more colours (:attr:`World.n_blobs` > 3, a static field), a tile of ``c >= 4`` colours
    also has one at the centre of each of its ``c`` parts (four samples leave some parts of five
    or six without one). A blob is in view when a sample of its part is; its bearing is the
    mean of those samples'. A world whose tiles have at most 3 colours compiles the three-blob
    reading alone, and a tile of 1 to 3 colours reads the same in either."""
    tiles = world.tiles[maze_index]  # (B, T, 6)
    colors = world.tile_colors[maze_index]  # (B, T)
    th = pose[..., 2]
    c, s = jnp.cos(th), jnp.sin(th)
    camx = pose[..., 0] + c * CAMERA_POSITION[0]
    camy = pose[..., 1] + s * CAMERA_POSITION[0]
    u = jnp.asarray(_TILE_SAMPLES, pose.dtype)  # (k,)
    # sample points across the width: centre + u * width * (-sin h, cos h)
    px = tiles[..., 0:1] - u * tiles[..., 4:5] * tiles[..., 3:4]  # (B, T, k)
    py = tiles[..., 1:2] + u * tiles[..., 4:5] * tiles[..., 2:3]
    many = world.n_blobs > BASE_BLOBS
    if many:  # the centres of the parts of tiles of 4 or more colours, after the four samples
        centre_table, part_table = _blob_tables(world.n_blobs)
        uc = jnp.asarray(centre_table, pose.dtype)[colors]  # (B, T, n)
        px = jnp.concatenate([px, tiles[..., 0:1] - uc * tiles[..., 4:5] * tiles[..., 3:4]], -1)
        py = jnp.concatenate([py, tiles[..., 1:2] + uc * tiles[..., 4:5] * tiles[..., 2:3]], -1)
    vx, vy = px - camx[:, None, None], py - camy[:, None, None]
    dist = jnp.hypot(vx, vy)
    # unit direction to each sample and the cosine of its angle off the camera's axis: the
    # field-of-view test and the occlusion rays need no angle (the bearings do; XLA drops them
    # where they are not used, as in the rollout)
    inv = 1.0 / jnp.maximum(dist, 1e-9)
    ux, uy = vx * inv, vy * inv
    cos_off = ux * c[:, None, None] + uy * s[:, None, None]
    b, t, k = px.shape
    in_view = (
        (colors[..., None] > 0)
        & (cos_off >= math.cos(math.radians(camera.fov_deg) / 2))
        & (dist <= camera.range)
    )
    steps = march_steps(world, camera.range)
    centre_dist = jnp.hypot(tiles[..., 0] - camx[:, None], tiles[..., 1] - camy[:, None])
    free = cast_along(
        world,
        mc,
        words,
        ci,
        cj,
        jnp.broadcast_to(camx[:, None], (b, t * k)),
        jnp.broadcast_to(camy[:, None], (b, t * k)),
        ux.reshape(b, t * k),
        uy.reshape(b, t * k),
        camera.range,
        steps=steps,
    ).reshape(b, t, k)
    seen = in_view & (free >= dist - 1e-4)
    rel = jnp.arctan2(uy * c[:, None, None] - ux * s[:, None, None], cos_off)
    if many:
        visible, bearing = _many_blobs(seen, rel, jnp.asarray(part_table)[colors], world.n_blobs)
        blobs = jnp.sum(visible, axis=(-1, -2))
        any_vis = jnp.any(visible, -1)
    else:
        visible, bearing, (vis0, vis1, vis2) = _three_blobs(seen, rel, colors, u)
        blobs = jnp.sum(visible, axis=(-1, -2))
        any_vis = vis0 | vis1 | vis2
    nearest_t = jnp.argmin(jnp.where(any_vis, centre_dist, jnp.inf), axis=-1)
    nearest = jnp.where(
        jnp.any(any_vis, -1), jnp.take_along_axis(colors, nearest_t[:, None], -1)[:, 0], 0
    )
    return CameraReading(blobs=blobs, nearest=nearest, visible=visible, bearing=bearing)


def _mean_bearing(mask: Array, rel: Array) -> Array:
    n = jnp.maximum(jnp.sum(mask, -1), 1)
    return jnp.sum(jnp.where(mask, rel, 0.0), -1) / n


def _three_blobs(
    seen: Array, rel: Array, colors: Array, u: Array
) -> tuple[Array, Array, tuple[Array, Array, Array]]:
    """Visibility and bearing ``(B, T, 3)`` of the blobs of tiles of at most 3 colours from
    their four samples ``seen``, ``rel`` ``(B, T, 4)``, and the three visibilities apart."""
    # blob b of a tile of c colours: the samples in the b-th of c equal parts of its width
    # (first: the u < 0 side); one colour: all of them
    two = (colors == 2)[..., None]
    three = (colors == 3)[..., None]
    left, right = u < 0, u > 0
    first_third, last_third = u < -1 / 6, u > 1 / 6
    middle = ~first_third & ~last_third
    blob0 = jnp.where(two, seen & left, jnp.where(three, seen & first_third, seen))
    blob1 = jnp.where(two, seen & right, jnp.where(three, seen & middle, False))
    blob2 = jnp.where(three, seen & last_third, False)
    vis0, vis1, vis2 = jnp.any(blob0, -1), jnp.any(blob1, -1), jnp.any(blob2, -1)
    visible = jnp.stack([vis0, vis1, vis2], -1)  # (B, T, 3)
    bearing = jnp.stack(
        [_mean_bearing(blob0, rel), _mean_bearing(blob1, rel), _mean_bearing(blob2, rel)], -1
    )
    return visible, bearing, (vis0, vis1, vis2)


def _many_blobs(seen: Array, rel: Array, part: Array, n_blobs: int) -> tuple[Array, Array]:
    """Visibility and bearing ``(B, T, n_blobs)`` from the samples ``seen``, ``rel``
    ``(B, T, 4 + n_blobs)``, each in the blob ``part`` (-1 none; :func:`_blob_tables`). The four
    samples and the extra ones are summed apart, so that a tile of 1 to 3 colours (no extra
    sample) reads the bearings :func:`_three_blobs` gives."""
    k = len(_TILE_SAMPLES)
    visible, bearing = [], []
    for blob in range(n_blobs):
        mask = seen & (part == blob)
        n = jnp.maximum(jnp.sum(mask[..., :k], -1) + jnp.sum(mask[..., k:], -1), 1)
        total = jnp.sum(jnp.where(mask[..., :k], rel[..., :k], 0.0), -1) + jnp.sum(
            jnp.where(mask[..., k:], rel[..., k:], 0.0), -1
        )
        visible.append(jnp.any(mask, -1))
        bearing.append(total / n)
    return jnp.stack(visible, -1), jnp.stack(bearing, -1)


def tile_under(world: World, maze_index: Array, pose: Array) -> Array:
    """The number of colours (0 none, 1 to 6) of the tile under the middle of the body."""
    tiles = world.tiles[maze_index]
    colors = world.tile_colors[maze_index]
    th = pose[..., 2:3]
    mx = pose[..., 0:1] + jnp.cos(th) * CAMERA_POSITION[0]
    my = pose[..., 1:2] + jnp.sin(th) * CAMERA_POSITION[0]
    dx, dy = mx - tiles[..., 0], my - tiles[..., 1]
    along = dx * tiles[..., 2] + dy * tiles[..., 3]
    across = -dx * tiles[..., 3] + dy * tiles[..., 2]
    inside = (
        (colors > 0)
        & (jnp.abs(along) <= tiles[..., 5] / 2)
        & (jnp.abs(across) <= tiles[..., 4] / 2)
    )
    return jnp.max(jnp.where(inside, colors, 0), axis=-1)
