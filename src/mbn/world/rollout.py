"""Batched, jitted robot episodes: many controllers x start poses x mazes in one ``lax.scan``.

One robot step (default 100 ms, as Stage's ``interval_sim``):

1. sense at the current pose: the sonars of :class:`~mbn.world.sensors.SensorConfig` (exact rays,
   optional Gaussian noise), the camera (when configured), and the tile under the body (the last
   tile driven over stays "in force");
2. the controller maps ``(controller_state, observation)`` to ``(controller_state, (v, w))``; it
   integrates its own network with as many sub-steps as it needs;
3. the command gets optional Gaussian noise and is clipped to the P3DX limits; the pose moves by
   forward Euler with the heading at the start of the step;
4. a move that would make the body overlap a wall is undone and counted as a stall (Stage's rule);
5. junctions: entering and leaving a decision cell of a grid maze records a junction pass, the exit
   taken and the exits the right- and left-hand rules take there.

The controller is written for ONE robot; the rollout vmaps it over the batch, so its state may be
any pytree (weights included, so that a batch of genomes is just a batch of states).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array, lax
from jax.typing import ArrayLike

from mbn.errors import MbnInputError
from mbn.world.engine import (
    CameraConfig,
    World,
    cast,
    collides_cells,
    maze_constants,
    see_tiles,
    tile_under,
    window_words,
)
from mbn.world.robot import (
    MAX_ANGULAR_SPEED,
    MAX_LINEAR_SPEED,
    SONAR_MAX_RANGE,
    SONAR_POSES,
    normalize_angle,
)
from mbn.world.sensors import NoiseConfig, SensorConfig, normalize, paper_inputs

__all__ = [
    "EXIT_NAMES",
    "EpisodeStats",
    "Observation",
    "RolloutConfig",
    "RolloutResult",
    "Trajectory",
    "episode_batch",
    "junction_arrays",
    "rollout",
]

#: Codes of junction exits (relative to the direction the robot entered in).
EXIT_NAMES = ("back", "right", "straight", "left")
_HEADINGS = "NESW"

Controller = Callable[[Any, "Observation"], tuple[Any, tuple[Array, Array]]]


class Observation(NamedTuple):
    """What a controller sees at one step (for one robot; batched inside the rollout).

    ``ranges``: the configured sonars (metres); ``S``: their normalised values; ``inputs``: the
    paper's I1..I3 (eq. 3; zeros when the paper's 10 sonars are not all cast); ``camera``: colours
    of the nearest tile in view (0 none, 1, 2); ``blobs``: blobs in view; ``tile``: colours of the
    last tile driven over (0 none yet); ``stalled``: whether the previous move was undone;
    ``t``: time (s).
    """

    ranges: Array
    S: Array
    inputs: Array
    camera: Array
    blobs: Array
    tile: Array
    stalled: Array
    t: Array


@dataclass(frozen=True)
class RolloutConfig:
    """Settings of a rollout.

    ``steps`` robot steps of ``dt`` seconds; ``camera`` None switches the camera off (it then
    reads 0); ``record_every`` > 0 records a trajectory sample every that many steps (the first
    sample is the start); ``max_junctions`` junction passes are kept per episode (all are counted).
    """

    steps: int = 200
    dt: float = 0.1
    sensors: SensorConfig = field(default_factory=SensorConfig)
    camera: CameraConfig | None = None
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    record_every: int = 0
    record_controller: bool = False
    max_junctions: int = 8

    def __post_init__(self) -> None:
        if not (isinstance(self.steps, int) and self.steps >= 1):
            raise MbnInputError(f"steps must be an integer >= 1, got {self.steps!r}")
        if not (self.dt > 0 and math.isfinite(self.dt)):
            raise MbnInputError(f"dt must be > 0, got {self.dt!r}")
        if self.record_every < 0:
            raise MbnInputError(f"record_every must be >= 0, got {self.record_every!r}")
        if self.max_junctions < 1:
            raise MbnInputError(f"max_junctions must be >= 1, got {self.max_junctions!r}")


class EpisodeStats(NamedTuple):
    """Per-episode statistics (leading axis: the batch).

    ``stall_fraction``; ``mean_v`` (actual signed linear speed, m/s) and ``mean_abs_w`` (rad/s);
    ``min_range`` (shortest sonar reading, metres); ``range_mean`` ``(B, k)`` mean reading of each
    configured sonar (metres) and ``S_mean`` its normalised mean; ``distance`` travelled (m);
    ``final_pose`` ``(B, 3)``; ``tile`` the tile in force at the end; junctions: ``n_junctions``
    passes in all, and for the first ``max_junctions`` of them ``junction_cell`` (row, col) of the
    maze grid, ``junction_heading`` (0..3 = N, E, S, W: direction of entry), ``junction_exit``,
    ``junction_right`` and ``junction_left`` (exit codes of :data:`EXIT_NAMES`: taken, and what
    the right- and left-hand rules take), ``junction_tile`` (tile in force on entry) and
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
    junction_tile: Array
    junction_step: Array
    junction_exit_step: Array
    junction_stalls: Array


class Trajectory(NamedTuple):
    """Samples every ``record_every`` steps: ``t (n,)``; per robot ``pose (B, n, 3)`` (before the
    step's move), ``ranges (B, n, k)``, ``camera``, ``blobs``, ``tile``, ``v``, ``w`` (applied),
    ``stalled``, and ``controller`` (the controller state pytree, if recorded)."""

    t: Array
    pose: Array
    ranges: Array
    camera: Array
    blobs: Array
    tile: Array
    v: Array
    w: Array
    stalled: Array
    controller: Any


class RolloutResult(NamedTuple):
    """Statistics, the optional trajectory, and the final controller states."""

    stats: EpisodeStats
    trajectory: Trajectory | None
    controller_state: Any


def junction_arrays(mazes: list[Any] | tuple[Any, ...], world: World) -> Array:
    """Rule-exit tables aligned with ``world.windows`` rows: ``(rows, 4, 2)`` int8 (entry heading
    N, E, S, W; right rule, left rule); -1 where the cell is not a decision cell."""
    from mbn.world.junctions import junction_tables

    total = int(world.windows.shape[0])
    out = np.full((total, 4, 2), -1, dtype=np.int8)
    shapes = np.asarray(world.shape)
    offsets = np.asarray(world.offset)
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
        # lattice row of cell (i = col, j = R-1-row) is offset + i * ny + j
        for r in range(rows):
            for c in range(cols):
                idx = offsets[k] + c * ny + (rows - 1 - r)
                out[idx, :, 0] = right[r, c]
                out[idx, :, 1] = left[r, c]
    return jnp.asarray(out)


def episode_batch(
    mazes: list[Any] | tuple[Any, ...], n_controllers: int, *, first_start_only: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The batch of every controller x every (maze, start pose), controller-major.

    Returns ``(controller_index (B,), poses (B, 3), maze_index (B,))``; index a batched controller
    state with ``controller_index`` (e.g. ``jax.tree.map(lambda a: a[idx], state)``).
    """
    if n_controllers < 1:
        raise MbnInputError(f"n_controllers must be >= 1, got {n_controllers}")
    pairs = []
    for m, maze in enumerate(mazes):
        starts = maze.starts[:1] if first_start_only else maze.starts
        if len(starts) == 0:
            raise MbnInputError(f"maze {maze.name!r} has no start pose")
        pairs += [(m, pose) for pose in starts]
    controller = np.repeat(np.arange(n_controllers), len(pairs))
    maze_index = np.tile(np.array([m for m, _ in pairs]), n_controllers)
    poses = np.tile(np.array([p for _, p in pairs]), (n_controllers, 1))
    return controller, poses, maze_index


def _relative_exit(entry: Array, move: Array) -> Array:
    """Exit code (0 back, 1 right, 2 straight, 3 left) of moving ``move`` after entering ``entry``
    (compass 0..3 = N, E, S, W)."""
    rel = (move - entry) % 4  # 0 straight, 1 right, 2 back, 3 left
    return jnp.asarray([2, 1, 0, 3], jnp.int32)[rel]


def rollout(
    world: World,
    controller: Controller,
    controller_state: Any,
    poses: ArrayLike,
    maze_index: ArrayLike,
    config: RolloutConfig,
    *,
    junctions: Array | None = None,
    key: Array | None = None,
) -> RolloutResult:
    """Run a batch of episodes (not jitted here: wrap it in :func:`jax.jit` with ``controller``
    and ``config`` static, or use :func:`make_rollout`).

    Args:
        world: compiled mazes (:func:`mbn.world.engine.compile_mazes`).
        controller: ``(state, observation) -> (state, (v, w))`` for one robot.
        controller_state: initial states, a pytree whose leaves have the batch as leading axis.
        poses: start poses ``(B, 3)``.
        maze_index: ``(B,)`` index of each robot's maze in ``world``.
        config: steps, step size, sensors, camera, noise, recording.
        junctions: tables from :func:`junction_arrays` (None: no junction tracking).
        key: PRNG key for noise (required when noise is on).
    """
    poses = jnp.asarray(poses)
    dtype = poses.dtype
    maze_index = jnp.asarray(maze_index, jnp.int32)
    b = poses.shape[0]
    if poses.shape != (b, 3) or maze_index.shape != (b,):
        raise MbnInputError(
            f"poses must be (B, 3) and maze_index (B,), got {poses.shape} and {maze_index.shape}"
        )
    if config.noise.enabled and key is None:
        raise MbnInputError("noise is on: pass a PRNG key")
    # the world's geometry in the poses' precision (float32 or float64)
    world = dataclasses.replace(
        world,
        origin=world.origin.astype(dtype),
        cell=world.cell.astype(dtype),
        tiles=world.tiles.astype(dtype),
    )
    sensors = config.sensors
    paper_pos = sensors.paper_positions
    sp = jnp.asarray(SONAR_POSES[list(sensors.sonars)], dtype)  # (k, 3)
    k = len(sensors.sonars)
    mc = maze_constants(world, maze_index)
    dt = config.dt
    jmax = config.max_junctions
    if junctions is None:
        junctions = jnp.full((int(world.windows.shape[0]), 4, 2), -1, jnp.int8)
    ny_all = mc.shape[..., 1]
    step_ctrl = jax.vmap(controller)

    def cast_at(pose: Array, words: Array, ci: Array, cj: Array, step: Array) -> Array:
        th = pose[:, 2:3]
        c, s = jnp.cos(th), jnp.sin(th)
        ox = pose[:, 0:1] + c * sp[:, 0] - s * sp[:, 1]
        oy = pose[:, 1:2] + s * sp[:, 0] + c * sp[:, 1]
        ranges = cast(world, mc, words, ci, cj, ox, oy, th + jnp.deg2rad(sp[:, 2]))
        if config.noise.sonar_std > 0:
            nk = jax.random.fold_in(jax.random.fold_in(key, step), 0)  # type: ignore[arg-type]
            noise = config.noise.sonar_std * jax.random.normal(nk, ranges.shape, dtype)
            ranges = jnp.clip(ranges + noise, 0.0, SONAR_MAX_RANGE)
        return ranges

    def command(v_cmd: Array, w_cmd: Array, step: Array) -> tuple[Array, Array]:
        if config.noise.v_std > 0 or config.noise.w_std > 0:
            nk = jax.random.fold_in(jax.random.fold_in(key, step), 1)  # type: ignore[arg-type]
            n = jax.random.normal(nk, (b, 2), dtype)
            v_cmd = v_cmd + config.noise.v_std * n[:, 0]
            w_cmd = w_cmd + config.noise.w_std * n[:, 1]
        v = jnp.clip(v_cmd, -MAX_LINEAR_SPEED, MAX_LINEAR_SPEED)
        w = jnp.clip(w_cmd, -MAX_ANGULAR_SPEED, MAX_ANGULAR_SPEED)
        return v, w

    # The step is pipelined: everything expensive (sonar rays, collision test) is computed for
    # the candidate pose at the END of a step and carried; the next step first resolves the move
    # (keep the candidate, or undo it if it collides). The expensive results thus have one
    # consumer (the loop carry), so the compiler does not duplicate them into every use.
    class Moved(NamedTuple):
        pose: Array
        words: Array
        ci: Array
        cj: Array
        ranges: Array

    class Carry(NamedTuple):
        prev: Moved  # where the robot is before the pending move
        cand: Moved  # where the pending move would take it
        hit: Array  # whether the pending move collides
        v: Array  # the pending move's speeds
        w: Array
        ctrl: Any
        tile: Array
        n_stall: Array
        sum_v: Array
        sum_abs_w: Array
        min_range: Array
        sum_range: Array
        sum_S: Array
        dist: Array
        in_pass: Array
        entry: Array
        n_junc: Array
        j_cell: Array
        j_head: Array
        j_exit: Array
        j_right: Array
        j_left: Array
        j_tile: Array
        j_step: Array
        j_out: Array
        j_stalls: Array

    def resolve(carry: Carry) -> tuple[Moved, dict[str, Array]]:
        """Apply the pending move (or undo it) and account for it."""
        hit = carry.hit
        here = jax.tree.map(
            lambda p, c: jnp.where(hit.reshape(-1, *([1] * (p.ndim - 1))), p, c),
            carry.prev,
            carry.cand,
        )
        v_act = jnp.where(hit, 0.0, carry.v)
        w_act = jnp.where(hit, 0.0, carry.w)
        acc = {
            "n_stall": carry.n_stall + hit.astype(jnp.int32),
            "sum_v": carry.sum_v + v_act,
            "sum_abs_w": carry.sum_abs_w + jnp.abs(w_act),
            "dist": carry.dist + jnp.abs(v_act) * dt,
            "v_act": v_act,
            "w_act": w_act,
        }
        return here, acc

    def junction_update(
        carry: Carry, here: Moved, tile: Array, step: Array, n_stall: Array
    ) -> dict[str, Array]:
        ci, cj = here.ci, here.cj
        pci, pcj = carry.prev.ci, carry.prev.cj
        moved = (ci != pci) | (cj != pcj)
        di, dj = ci - pci, cj - pcj
        # compass of the move (dominant axis; ties go to north-south, as junction_sequence)
        heading = jnp.where(
            jnp.abs(dj) >= jnp.abs(di), jnp.where(dj > 0, 0, 2), jnp.where(di > 0, 1, 3)
        ).astype(jnp.int32)
        closing = moved & carry.in_pass
        slots = jnp.arange(jmax)
        write = closing[:, None] & (slots == carry.n_junc[:, None])  # (B, J)
        j_exit = jnp.where(write, _relative_exit(carry.entry, heading)[:, None], carry.j_exit)
        j_out = jnp.where(write, step, carry.j_out)
        j_stalls = jnp.where(write, n_stall[:, None], carry.j_stalls)
        n_junc = carry.n_junc + closing.astype(jnp.int32)
        nx_, ny_ = mc.shape[:, 0], mc.shape[:, 1]
        inside = (ci >= 0) & (ci < nx_) & (cj >= 0) & (cj < ny_)
        lattice_row = jnp.where(inside, mc.offset + ci * ny_ + cj, 0)
        rule = junctions[lattice_row, heading].astype(jnp.int32)  # (B, 2)
        opening = moved & inside & (rule[:, 0] >= 0)
        write2 = opening[:, None] & (slots == n_junc[:, None])  # (B, J)

        def put(arr: Array, value: Array) -> Array:
            return jnp.where(write2, value[:, None], arr)

        cell = jnp.stack([ny_all - 1 - cj, ci], -1)
        return {
            "in_pass": jnp.where(moved, opening, carry.in_pass),
            "entry": jnp.where(opening, heading, carry.entry),
            "n_junc": n_junc,
            "j_cell": jnp.where(write2[..., None], cell[:, None, :], carry.j_cell),
            "j_head": put(carry.j_head, heading),
            "j_exit": j_exit,
            "j_right": put(carry.j_right, rule[:, 0]),
            "j_left": put(carry.j_left, rule[:, 1]),
            "j_tile": put(carry.j_tile, tile),
            "j_step": put(carry.j_step, jnp.broadcast_to(step, (b,))),
            "j_out": j_out,
            "j_stalls": j_stalls,
        }

    def one_step(carry: Carry, step: Array) -> tuple[Carry, tuple[Any, ...]]:
        step = jnp.asarray(step, jnp.int32)
        here, acc = resolve(carry)
        pose = here.pose
        ranges = here.ranges
        S = normalize(ranges, sensors)
        if paper_pos is not None:
            inputs = paper_inputs(S[:, list(paper_pos)])
        else:
            inputs = jnp.zeros((b, 3), dtype)
        if config.camera is not None:
            cam = see_tiles(
                world, mc, maze_index, here.words, here.ci, here.cj, pose, config.camera
            )
            camera, blobs = cam.nearest, cam.blobs
        else:
            camera = blobs = jnp.zeros((b,), jnp.int32)
        under = tile_under(world, maze_index, pose)
        tile = jnp.where(under > 0, under, carry.tile)
        t = jnp.broadcast_to(step.astype(dtype) * dt, (b,))
        obs = Observation(ranges, S, inputs, camera, blobs, tile, carry.hit, t)
        ctrl, (v_cmd, w_cmd) = step_ctrl(carry.ctrl, obs)
        v, w = command(jnp.asarray(v_cmd, dtype), jnp.asarray(w_cmd, dtype), step)
        x, y, th = pose[:, 0], pose[:, 1], pose[:, 2]
        cand_pose = jnp.stack(
            [x + v * dt * jnp.cos(th), y + v * dt * jnp.sin(th), normalize_angle(th + w * dt)], -1
        )
        words_c, ci_c, cj_c = window_words(world, mc, cand_pose[:, 0], cand_pose[:, 1])
        hit = collides_cells(world, mc, words_c, ci_c, cj_c, cand_pose)
        cand = Moved(cand_pose, words_c, ci_c, cj_c, cast_at(cand_pose, words_c, ci_c, cj_c, step))
        junc = junction_update(carry, here, tile, step, acc["n_stall"])
        new = Carry(
            prev=here,
            cand=cand,
            hit=hit,
            v=v,
            w=w,
            ctrl=ctrl,
            tile=tile,
            n_stall=acc["n_stall"],
            sum_v=acc["sum_v"],
            sum_abs_w=acc["sum_abs_w"],
            min_range=jnp.minimum(carry.min_range, jnp.min(ranges, -1)),
            sum_range=carry.sum_range + ranges,
            sum_S=carry.sum_S + S,
            dist=acc["dist"],
            **junc,
        )
        record: tuple[Any, ...] = (pose, ranges, camera, blobs, tile, v, w, carry.hit)
        if config.record_controller:
            record = (*record, carry.ctrl)
        return new, record

    words0, ci0, cj0 = window_words(world, mc, poses[:, 0], poses[:, 1])
    start = Moved(poses, words0, ci0, cj0, cast_at(poses, words0, ci0, cj0, jnp.asarray(-1)))
    neg = jnp.full((b, jmax), -1, jnp.int32)
    carry0 = Carry(
        prev=start,
        cand=start,
        hit=jnp.zeros((b,), bool),
        v=jnp.zeros((b,), dtype),
        w=jnp.zeros((b,), dtype),
        ctrl=controller_state,
        tile=jnp.zeros((b,), jnp.int32),
        n_stall=jnp.zeros((b,), jnp.int32),
        sum_v=jnp.zeros((b,), dtype),
        sum_abs_w=jnp.zeros((b,), dtype),
        min_range=jnp.full((b,), SONAR_MAX_RANGE, dtype),
        sum_range=jnp.zeros((b, k), dtype),
        sum_S=jnp.zeros((b, k), dtype),
        dist=jnp.zeros((b,), dtype),
        in_pass=jnp.zeros((b,), bool),
        entry=jnp.zeros((b,), jnp.int32),
        n_junc=jnp.zeros((b,), jnp.int32),
        j_cell=jnp.full((b, jmax, 2), -1, jnp.int32),
        j_head=neg,
        j_exit=neg,
        j_right=neg,
        j_left=neg,
        j_tile=neg,
        j_step=neg,
        j_out=neg,
        j_stalls=neg,
    )
    steps = config.steps
    every = config.record_every
    if every > 0:
        n_rec = steps // every

        def chunk(carry: Carry, c: Array) -> tuple[Carry, tuple[Any, ...]]:
            carry, rec = one_step(carry, c * every)
            if every > 1:
                carry, _ = lax.scan(
                    lambda cr, s: (one_step(cr, s)[0], None),
                    carry,
                    c * every + jnp.arange(1, every),
                )
            return carry, rec

        carry, recs = lax.scan(chunk, carry0, jnp.arange(n_rec))
        rest = steps - n_rec * every
        if rest:
            carry, _ = lax.scan(
                lambda cr, s: (one_step(cr, s)[0], None), carry, n_rec * every + jnp.arange(rest)
            )
        swap = lambda a: jnp.swapaxes(a, 0, 1)  # noqa: E731
        ctrl_rec = jax.tree.map(swap, recs[8]) if config.record_controller else None
        trajectory: Trajectory | None = Trajectory(
            t=jnp.arange(n_rec, dtype=dtype) * every * dt,
            pose=swap(recs[0]),
            ranges=swap(recs[1]),
            camera=swap(recs[2]),
            blobs=swap(recs[3]),
            tile=swap(recs[4]),
            v=swap(recs[5]),
            w=swap(recs[6]),
            stalled=swap(recs[7]),
            controller=ctrl_rec,
        )
    else:
        carry, _ = lax.scan(lambda cr, s: (one_step(cr, s)[0], None), carry0, jnp.arange(steps))
        trajectory = None
    final, acc = resolve(carry)
    junc = junction_update(carry, final, carry.tile, jnp.asarray(steps, jnp.int32), acc["n_stall"])
    n = float(steps)
    stats = EpisodeStats(
        stall_fraction=acc["n_stall"].astype(dtype) / n,
        mean_v=acc["sum_v"] / n,
        mean_abs_w=acc["sum_abs_w"] / n,
        min_range=carry.min_range,
        range_mean=carry.sum_range / n,
        S_mean=carry.sum_S / n,
        distance=acc["dist"],
        final_pose=final.pose,
        tile=carry.tile,
        n_junctions=junc["n_junc"],
        junction_cell=junc["j_cell"],
        junction_heading=junc["j_head"],
        junction_exit=junc["j_exit"],
        junction_right=junc["j_right"],
        junction_left=junc["j_left"],
        junction_tile=junc["j_tile"],
        junction_step=junc["j_step"],
        junction_exit_step=junc["j_out"],
        junction_stalls=junc["j_stalls"],
    )
    return RolloutResult(stats=stats, trajectory=trajectory, controller_state=carry.ctrl)
