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


def _has_free_space(maze: Maze) -> bool:
    """Whether some point of a walled maze's bounds is not inside a wall (exact: the walls' edge
    coordinates cut the bounds into cells, each wholly free or wholly solid)."""
    if not maze.outside_is_wall:
        return True
    x0, x1, y0, y1 = maze.bounds
    w = maze.walls
    xs = np.unique(np.clip(np.concatenate([[x0, x1], w[:, 0], w[:, 1]]), x0, x1))
    ys = np.unique(np.clip(np.concatenate([[y0, y1], w[:, 2], w[:, 3]]), y0, y1))
    cx = (xs[:-1] + xs[1:]) / 2
    cy = (ys[:-1] + ys[1:]) / 2
    if cx.size == 0 or cy.size == 0:
        return False
    inx = (w[:, 0][None, :] < cx[:, None]) & (cx[:, None] < w[:, 1][None, :])  # (X, K)
    iny = (w[:, 2][None, :] < cy[:, None]) & (cy[:, None] < w[:, 3][None, :])  # (Y, K)
    # a cell (i, j) is solid if some wall k covers both its x and y centre
    covered = (inx.astype(np.int32) @ iny.T.astype(np.int32)) > 0  # (X, Y)
    return not bool(np.all(covered))


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
