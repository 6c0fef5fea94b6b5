"""Checks every maze passes, and reading a maze file's text.

:func:`validate_maze` is called by every reader (:mod:`~mbn.world.mazes.grid_text`,
:mod:`~mbn.world.mazes.toml_maze`, :mod:`~mbn.world.mazes.stage`) and by the built-in mazes
(:mod:`~mbn.world.mazes.builtin`); :func:`read_text` is how the file readers open their files.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mbn.errors import MbnInputError
from mbn.world.mazes.model import Maze

__all__ = ["read_text", "validate_maze"]


def read_text(path: str | os.PathLike[str]) -> str:
    """The text of ``path`` (UTF-8), or an :class:`MbnInputError` naming it."""
    p = Path(path)
    if not p.exists():
        raise MbnInputError(f"{p}: no such file")
    if p.is_dir():
        raise MbnInputError(f"{p}: is a folder, not a file")
    try:
        return p.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise MbnInputError(f"{p}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise MbnInputError(f"{p}: cannot read ({exc.strerror})") from None


def _fmt_pose(pose: np.ndarray) -> str:
    return f"({pose[0]:g}, {pose[1]:g}, {math.degrees(pose[2]):g} deg)"


#: Cells of the compressed coordinate grid up to which free space is found by a difference array
#: (memory 4 bytes a cell); beyond it, by a sweep line with a segment tree (memory linear in the
#: number of walls).
_DIRECT_CELLS = 16_000_000


def _has_free_space(maze: Maze) -> bool:
    """Whether some point of a walled maze's bounds is not inside a wall (exact: the walls' edge
    coordinates cut the bounds into cells, each wholly free or wholly solid). Time and memory grow
    with the number of walls (``O(K log K)``, or the compressed grid when it is small), never with
    their product with the grid."""
    if not maze.outside_is_wall:
        return True
    x0, x1, y0, y1 = maze.bounds
    w = maze.walls
    if w.shape[0] == 0:
        return x1 > x0 and y1 > y0
    xs = np.unique(np.clip(np.concatenate([[x0, x1], w[:, 0], w[:, 1]]), x0, x1))
    ys = np.unique(np.clip(np.concatenate([[y0, y1], w[:, 2], w[:, 3]]), y0, y1))
    if xs.size < 2 or ys.size < 2:
        return False
    # each wall covers the compressed cells [i0, i1) x [j0, j1)
    i0 = np.searchsorted(xs, np.clip(w[:, 0], x0, x1))
    i1 = np.searchsorted(xs, np.clip(w[:, 1], x0, x1))
    j0 = np.searchsorted(ys, np.clip(w[:, 2], y0, y1))
    j1 = np.searchsorted(ys, np.clip(w[:, 3], y0, y1))
    keep = (i1 > i0) & (j1 > j0)
    i0, i1, j0, j1 = i0[keep], i1[keep], j0[keep], j1[keep]
    nx, ny = xs.size - 1, ys.size - 1
    if nx * ny <= _DIRECT_CELLS:
        diff = np.zeros((nx + 1, ny + 1), np.int32)
        np.add.at(diff, (i0, j0), 1)
        np.add.at(diff, (i0, j1), -1)
        np.add.at(diff, (i1, j0), -1)
        np.add.at(diff, (i1, j1), 1)
        cover = diff.cumsum(0).cumsum(1)[:nx, :ny]
        return bool(np.any(cover == 0))
    return _sweep_has_gap(i0, i1, j0, j1, nx, ny)


def _sweep_has_gap(
    i0: np.ndarray, i1: np.ndarray, j0: np.ndarray, j1: np.ndarray, nx: int, ny: int
) -> bool:
    """Whether the rectangles ``[i0, i1) x [j0, j1)`` of an ``nx x ny`` index grid leave a cell
    uncovered: a sweep over x with a segment tree holding, per node, the count of rectangles
    covering it whole and the least coverage below it."""
    size = 1
    while size < ny:
        size *= 2
    add = np.zeros(2 * size, np.int64)
    low = np.zeros(2 * size, np.int64)
    # cells beyond ny are padding: count them as covered
    low[size + ny : 2 * size] = 1 << 40
    for node in range(size - 1, 0, -1):
        low[node] = min(low[2 * node], low[2 * node + 1])

    def update(node: int, lo: int, hi: int, a: int, b: int, v: int) -> None:
        if b <= lo or hi <= a:
            return
        if a <= lo and hi <= b:
            add[node] += v
        else:
            mid = (lo + hi) // 2
            update(2 * node, lo, mid, a, b, v)
            update(2 * node + 1, mid, hi, a, b, v)
        if node >= size:
            low[node] = add[node] + (1 << 40 if node - size >= ny else 0)
        else:
            low[node] = add[node] + min(low[2 * node], low[2 * node + 1])

    events: dict[int, list[tuple[int, int, int]]] = {}
    for a0, a1, b0, b1 in zip(i0.tolist(), i1.tolist(), j0.tolist(), j1.tolist(), strict=True):
        events.setdefault(a0, []).append((b0, b1, 1))
        events.setdefault(a1, []).append((b0, b1, -1))
    xs = sorted(events)
    if not xs or xs[0] > 0:
        return True
    for k, x in enumerate(xs):
        if x >= nx:
            break
        for b0, b1, v in events[x]:
            update(1, 0, size, b0, b1, v)
        end = xs[k + 1] if k + 1 < len(xs) else nx
        if end > x and low[1] == 0:
            return True
    return xs[-1] < nx


def _bucket(n: int) -> int:
    return max(8, 1 << max(0, n - 1).bit_length())


@functools.cache
def _jitted_collides() -> Callable[[Any, Any], Any]:
    import jax

    from mbn.world.geometry import collides

    return jax.jit(collides)


def _starts_collide(starts: np.ndarray, rects: np.ndarray) -> np.ndarray:
    """:func:`mbn.world.geometry.collides` of every start against ``rects``, as bools ``(S,)``.

    Starts and rectangles are padded to power-of-two counts (copies of the first start; unit
    squares far from everything) so that the jitted check compiles once per size class rather than
    once per maze.
    """
    n_s, n_r = len(starts), len(rects)
    far = 1e6 + float(np.max(np.abs(rects))) + float(np.max(np.abs(starts[:, :2])))
    pad_s = np.repeat(starts[:1], _bucket(n_s) - n_s, axis=0)
    pad_r = np.tile([[far, far + 1.0, far, far + 1.0]], (_bucket(n_r) - n_r, 1))
    hits = _jitted_collides()(np.concatenate([starts, pad_s]), np.concatenate([rects, pad_r]))
    return np.asarray(hits, dtype=bool).reshape(-1)[:n_s]


def validate_maze(
    maze: Maze,
    where: str,
    *,
    start_labels: Sequence[str] | None = None,
    tile_labels: Sequence[str] | None = None,
) -> None:
    """Check that ``maze`` is usable; raise a one-line :class:`MbnInputError` otherwise.

    * it has free space;
    * no start pose's robot body overlaps a wall (:func:`mbn.world.geometry.collides` against
      :meth:`Maze.solid_rects`), and in a walled maze every start lies inside ``bounds``;
    * every tile's centre is in free space.

    Args:
        maze: the maze.
        where: the prefix of messages (a file name, or ``"file:line"``).
        start_labels, tile_labels: optional full prefixes, one per start / tile, replacing
            ``"{where}: start #k"`` / ``"{where}: tile #k"`` (e.g. with the file line of each).
    """
    if not _has_free_space(maze):
        raise MbnInputError(f"{where}: the maze has no free space")

    def start_label(k: int) -> str:
        if start_labels is not None:
            return start_labels[k]
        return f"{where}: start #{k + 1}"

    def tile_label(k: int) -> str:
        if tile_labels is not None:
            return tile_labels[k]
        return f"{where}: tile #{k + 1}"

    starts = maze.starts
    if starts.shape[0]:
        if maze.outside_is_wall:
            x0, x1, y0, y1 = maze.bounds
            for k, s in enumerate(starts):
                if not (x0 <= s[0] <= x1 and y0 <= s[1] <= y1):
                    raise MbnInputError(
                        f"{start_label(k)} at {_fmt_pose(s)} lies outside the maze's bounds"
                        f" [{x0:g}, {x1:g}] x [{y0:g}, {y1:g}]"
                    )
        rects = maze.solid_rects()
        if rects.shape[0]:
            hits = _starts_collide(starts, rects)
            bad = np.flatnonzero(hits)
            if bad.size:
                first = int(bad[0])
                raise MbnInputError(
                    f"{start_label(first)} at {_fmt_pose(starts[first])}: the robot's body"
                    " overlaps a wall"
                )
    for k, tile in enumerate(maze.tiles):
        if not maze.is_free(tile.x, tile.y):
            raise MbnInputError(
                f"{tile_label(k)} at ({tile.x:g}, {tile.y:g}): its centre is not in free space"
            )
