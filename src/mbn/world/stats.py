"""Per-episode bookkeeping of a rollout: running statistics and junction passes.

Pure JAX over a flat batch ``(B, ...)`` of robots; :mod:`mbn.world.rollout` updates a
:class:`Tally` and a :class:`JunctionLog` at every step and turns them into
:class:`EpisodeStats` at the end (:func:`episode_stats`).

Junction passes follow :func:`mbn.world.junctions.junction_sequence`: a pass opens when the robot
moves into a decision cell of a grid maze and closes when it moves into another cell; the entry
heading and the exit are the compass directions of those moves (dominant axis of the cell
displacement, ties north-south), and the exits the right- and left-hand rules take there come from
the tables of :func:`junction_arrays`.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax.numpy as jnp
import numpy as np
from jax import Array

from mbn.errors import MbnInputError
from mbn.host import put
from mbn.world.engine import MazeConstants, World

__all__ = [
    "EXIT_NAMES",
    "EpisodeStats",
    "JunctionLog",
    "Tally",
    "count_move",
    "count_sensing",
    "episode_stats",
    "junction_arrays",
    "junction_cell",
    "junction_constants",
    "log_junctions",
    "relative_exit",
    "start_junctions",
    "start_tally",
]

#: Codes of junction exits (relative to the direction the robot entered in).
EXIT_NAMES = ("back", "right", "straight", "left")


class EpisodeStats(NamedTuple):
    """Per-episode statistics (leading axis: the batch).

    ``stall_fraction``; ``mean_v`` (actual signed linear speed, m/s) and ``mean_abs_w`` (rad/s);
    ``min_range`` (shortest sonar reading, metres); ``range_mean`` ``(B, k)`` mean reading of each
    configured sonar (metres) and ``S_mean`` its normalised mean; ``distance`` travelled (m);
    ``final_pose`` ``(B, 3)``; ``tile`` the tile in force at the end; junctions: ``n_junctions``
    passes in all, and for the first ``max_junctions`` of them ``junction_cell`` (row, col) of the
    maze grid, ``junction_heading`` (0..3 = N, E, S, W: direction of entry), ``junction_exit``,
    ``junction_right`` and ``junction_left`` (exit codes of :data:`EXIT_NAMES`: taken, and what
    the right- and left-hand rules take), ``junction_open`` (the exits open there, a mask of
    :data:`mbn.world.rules.OPEN_BITS`: what any rule takes, :func:`mbn.world.rules.
    rule_exit_codes`), ``junction_tile`` (tile in force on entry) and
    ``junction_step`` (step of entry), ``junction_exit_step`` (step at which the robot is in the
    next cell) and ``junction_stalls`` (stalled moves from the start of the episode until then);
    entries beyond ``n_junctions`` are -1 (a pass still open at the end has no exit yet).
    """

    stall_fraction: Array
    mean_v: Array
    mean_abs_w: Array
    min_range: Array
    range_mean: Array
    S_mean: Array
    distance: Array
    final_pose: Array
    tile: Array
    n_junctions: Array
    junction_cell: Array
    junction_heading: Array
    junction_exit: Array
    junction_right: Array
    junction_left: Array
    junction_open: Array
    junction_tile: Array
    junction_step: Array
    junction_exit_step: Array
    junction_stalls: Array


def junction_arrays(mazes: list[Any] | tuple[Any, ...], world: World) -> Array:
    """Rule-exit tables aligned with ``world.windows`` rows (a grid of square cells is its
    lattice), then the cells of the grids with columns and rows of several widths
    (:attr:`World.grid_offset`): ``(world.n_junction_rows, 4, 3)`` int8 (entry heading N, E, S,
    W; the right rule's exit, the left rule's, and the mask of open exits,
    :data:`mbn.world.rules.OPEN_BITS`); -1 where the cell is not a decision cell."""
    from mbn.world.junctions import junction_tables

    total = world.n_junction_rows
    out = np.full((total, 4, 3), -1, dtype=np.int8)
    shapes = np.asarray(world.shape)
    offsets = np.asarray(world.offset)
    if world.grid_shape is not None and world.grid_offset is not None:
        on_edges = np.asarray(world.grid_shape)[:, 0] > 0
        shapes = np.where(on_edges[:, None], np.asarray(world.grid_shape), shapes)
        offsets = np.where(on_edges, np.asarray(world.grid_offset), offsets)
    for k, maze in enumerate(mazes):
        if maze.grid is None:
            continue
        tables = junction_tables(maze)
        rows, cols = maze.grid.shape
        nx, ny = shapes[k]
        if (nx, ny) != (cols, rows):  # pragma: no cover - grid mazes compile to their grid
            raise MbnInputError(f"maze {maze.name!r}: lattice does not match its grid")
        right = np.asarray(tables["right"])  # (R, C, 4)
        left = np.asarray(tables["left"])
        mask = np.asarray(tables["open_mask"])
        # lattice row of cell (i = col, j = R-1-row) is offset + i * ny + j
        for r in range(rows):
            for c in range(cols):
                idx = offsets[k] + c * ny + (rows - 1 - r)
                out[idx, :, 0] = right[r, c]
                out[idx, :, 1] = left[r, c]
                out[idx, :, 2] = mask[r, c]
    return put(out)


def junction_constants(world: World, mc: MazeConstants, maze_index: Array) -> MazeConstants:
    """The robots' maze constants as :func:`log_junctions` reads them: ``mc`` itself, except
    that for a grid with columns and rows of several widths ``shape`` is that grid's
    ``(columns, rows)`` and ``offset`` the junction-table row of its first cell."""
    if world.grid_shape is None or world.grid_offset is None:
        return mc
    shape = world.grid_shape[maze_index]
    on_edges = shape[..., 0] > 0
    return mc._replace(
        shape=jnp.where(on_edges[..., None], shape, mc.shape),
        offset=jnp.where(on_edges, world.grid_offset[maze_index], mc.offset),
    )


def junction_cell(
    world: World, maze_index: Array, pose: Array, ci: Array, cj: Array
) -> tuple[Array, Array]:
    """The cells :func:`log_junctions` records, ``(B,)`` each: the lattice (or culling) cell
    ``(ci, cj)``, except in a grid with columns and rows of several widths: the column and the row
    (from the south) of its grid holding ``pose``'s ``(x, y)`` (a point on a border belongs to
    the cell east / north of it; -1, or the count of columns or rows, outside)."""
    if world.grid_edges is None or world.grid_shape is None:
        return ci, cj
    edges = world.grid_edges[maze_index].astype(pose.dtype)  # (B, 2, E), padded with +inf
    gi = jnp.sum(edges[:, 0, :] <= pose[:, 0, None], axis=-1) - 1
    gj = jnp.sum(edges[:, 1, :] <= pose[:, 1, None], axis=-1) - 1
    on_edges = world.grid_shape[maze_index, 0] > 0
    return (
        jnp.where(on_edges, gi.astype(ci.dtype), ci),
        jnp.where(on_edges, gj.astype(cj.dtype), cj),
    )


# ---------------------------------------------------------------------------------------------
# running statistics


class Tally(NamedTuple):
    """Running sums of an episode ``(B,)``: ``n_stall`` (int32) undone moves; ``sum_v`` (m/s)
    and ``sum_abs_w`` (rad/s) of the speeds driven; ``dist`` (m) travelled; ``min_range`` (m)
    shortest reading; ``sum_range`` (m) and ``sum_S`` ``(B, k)`` of each sonar."""

    n_stall: Array
    sum_v: Array
    sum_abs_w: Array
    dist: Array
    min_range: Array
    sum_range: Array
    sum_S: Array


def start_tally(b: int, k: int, dtype: Any, max_range: float) -> Tally:
    """An empty :class:`Tally` for ``b`` robots with ``k`` sonars reading at most ``max_range``
    metres; float sums in ``dtype``."""
    return Tally(
        n_stall=jnp.zeros((b,), jnp.int32),
        sum_v=jnp.zeros((b,), dtype),
        sum_abs_w=jnp.zeros((b,), dtype),
        dist=jnp.zeros((b,), dtype),
        min_range=jnp.full((b,), max_range, dtype),
        sum_range=jnp.zeros((b, k), dtype),
        sum_S=jnp.zeros((b, k), dtype),
    )


def count_move(tally: Tally, stalled: Array, v: Array, w: Array, dt: float) -> Tally:
    """Account for one move of ``dt`` seconds: ``stalled (B,)`` whether it was undone, ``v``,
    ``w (B,)`` the speeds driven (0 where undone, :func:`mbn.world.step.applied_speeds`)."""
    return tally._replace(
        n_stall=tally.n_stall + stalled.astype(jnp.int32),
        sum_v=tally.sum_v + v,
        sum_abs_w=tally.sum_abs_w + jnp.abs(w),
        dist=tally.dist + jnp.abs(v) * dt,
    )


def count_sensing(tally: Tally, ranges: Array, S: Array) -> Tally:
    """Account for one step's sonar ``ranges (B, k)`` (metres) and their normalised ``S``."""
    return tally._replace(
        min_range=jnp.minimum(tally.min_range, jnp.min(ranges, -1)),
        sum_range=tally.sum_range + ranges,
        sum_S=tally.sum_S + S,
    )


# ---------------------------------------------------------------------------------------------
# junction passes


class JunctionLog(NamedTuple):
    """Junction passes so far ``(B, ...)``: ``in_pass`` whether the robot is in a decision cell it
    entered (a pass open), ``entry`` that pass's entry heading (0..3 = N, E, S, W), ``passes`` the
    passes closed; and for the first ``J`` passes ``(B, J)`` (-1 where none; ``cell (B, J, 2)``)
    the fields of :class:`EpisodeStats`' ``junction_*``: ``cell``, ``heading``, ``exit``,
    ``right``, ``left``, ``open``, ``tile``, ``step``, ``exit_step``, ``stalls``."""

    in_pass: Array
    entry: Array
    passes: Array
    cell: Array
    heading: Array
    exit: Array
    right: Array
    left: Array
    open: Array
    tile: Array
    step: Array
    exit_step: Array
    stalls: Array


def start_junctions(b: int, max_junctions: int) -> JunctionLog:
    """An empty :class:`JunctionLog` for ``b`` robots keeping ``max_junctions`` passes each."""
    neg = jnp.full((b, max_junctions), -1, jnp.int32)
    return JunctionLog(
        in_pass=jnp.zeros((b,), bool),
        entry=jnp.zeros((b,), jnp.int32),
        passes=jnp.zeros((b,), jnp.int32),
        cell=jnp.full((b, max_junctions, 2), -1, jnp.int32),
        heading=neg,
        exit=neg,
        right=neg,
        left=neg,
        open=neg,
        tile=neg,
        step=neg,
        exit_step=neg,
        stalls=neg,
    )


def relative_exit(entry: Array, move: Array) -> Array:
    """Exit code (0 back, 1 right, 2 straight, 3 left) of moving ``move`` after entering ``entry``
    (compass 0..3 = N, E, S, W)."""
    rel = (move - entry) % 4  # 0 straight, 1 right, 2 back, 3 left
    return jnp.asarray([2, 1, 0, 3], jnp.int32)[rel]


def log_junctions(
    log: JunctionLog,
    tables: Array,
    mc: MazeConstants,
    prev_cell: tuple[Array, Array],
    cell: tuple[Array, Array],
    tile: Array,
    step: Array,
    n_stall: Array,
) -> JunctionLog:
    """Record the junction passes that the move from lattice cell ``prev_cell`` to ``cell``
    (each ``(ci, cj)``, ``(B,)`` int32) closes and opens.

    Args:
        log: the passes so far.
        tables: rule exits of every lattice row (:func:`junction_arrays`).
        mc: the robots' maze constants.
        prev_cell: the cell before the move.
        cell: the cell after it.
        tile: ``(B,)`` the tile in force after the move (recorded for a pass opened).
        step: the step index (int32 scalar) at which the robot is in ``cell``.
        n_stall: ``(B,)`` the stalled moves so far (recorded for a pass closed).
    """
    ci, cj = cell
    pci, pcj = prev_cell
    b = ci.shape[0]
    jmax = log.heading.shape[1]
    moved = (ci != pci) | (cj != pcj)
    di, dj = ci - pci, cj - pcj
    # compass of the move (dominant axis; ties go to north-south, as junction_sequence)
    heading = jnp.where(
        jnp.abs(dj) >= jnp.abs(di), jnp.where(dj > 0, 0, 2), jnp.where(di > 0, 1, 3)
    ).astype(jnp.int32)
    closing = moved & log.in_pass
    slots = jnp.arange(jmax)
    write = closing[:, None] & (slots == log.passes[:, None])  # (B, J)
    exit_ = jnp.where(write, relative_exit(log.entry, heading)[:, None], log.exit)
    exit_step = jnp.where(write, step, log.exit_step)
    stalls = jnp.where(write, n_stall[:, None], log.stalls)
    passes = log.passes + closing.astype(jnp.int32)
    nx_, ny_ = mc.shape[:, 0], mc.shape[:, 1]
    inside = (ci >= 0) & (ci < nx_) & (cj >= 0) & (cj < ny_)
    lattice_row = jnp.where(inside, mc.offset + ci * ny_ + cj, 0)
    rule = tables[lattice_row, heading].astype(jnp.int32)  # (B, 3): right, left, open mask
    opening = moved & inside & (rule[:, 0] >= 0)
    write2 = opening[:, None] & (slots == passes[:, None])  # (B, J)

    def put(arr: Array, value: Array) -> Array:
        return jnp.where(write2, value[:, None], arr)

    grid_cell = jnp.stack([mc.shape[..., 1] - 1 - cj, ci], -1)
    return JunctionLog(
        in_pass=jnp.where(moved, opening, log.in_pass),
        entry=jnp.where(opening, heading, log.entry),
        passes=passes,
        cell=jnp.where(write2[..., None], grid_cell[:, None, :], log.cell),
        heading=put(log.heading, heading),
        exit=exit_,
        right=put(log.right, rule[:, 0]),
        left=put(log.left, rule[:, 1]),
        open=put(log.open, rule[:, 2]),
        tile=put(log.tile, tile),
        step=put(log.step, jnp.broadcast_to(step, (b,))),
        exit_step=exit_step,
        stalls=stalls,
    )


def episode_stats(
    tally: Tally, log: JunctionLog, final_pose: Array, tile: Array, steps: int
) -> EpisodeStats:
    """The :class:`EpisodeStats` of episodes of ``steps`` steps from their final tally and
    junction log, ``final_pose (B, 3)`` and the tile in force at the end ``(B,)``."""
    n = float(steps)
    return EpisodeStats(
        stall_fraction=tally.n_stall.astype(final_pose.dtype) / n,
        mean_v=tally.sum_v / n,
        mean_abs_w=tally.sum_abs_w / n,
        min_range=tally.min_range,
        range_mean=tally.sum_range / n,
        S_mean=tally.sum_S / n,
        distance=tally.dist,
        final_pose=final_pose,
        tile=tile,
        n_junctions=log.passes,
        junction_cell=log.cell,
        junction_heading=log.heading,
        junction_exit=log.exit,
        junction_right=log.right,
        junction_left=log.left,
        junction_open=log.open,
        junction_tile=log.tile,
        junction_step=log.step,
        junction_exit_step=log.exit_step,
        junction_stalls=log.stalls,
    )
