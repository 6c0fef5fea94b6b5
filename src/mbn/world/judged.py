"""Trials that stop once they are judged: a rollout run in chunks that drops the robots whose
verdict can no longer change and goes on with the others in a smaller batch
(``docs/speed.md``, "Trials stop once judged").

A trial is judged on its first ``J`` junction passes (:func:`mbn.experiments.trials.judge`):
the exits taken, the rule in force there, and the stalled moves until the J-th pass was left.
Once a robot has left its J-th counted pass, nothing it does afterwards reaches its verdict;
in the generated mazes that happens after about a seventh of the time limit, which is set by
the longest route of the batch's slowest maze (``docs/generalization.md``, "Cost"). So
:func:`run_rollout_until_judged` runs ``chunk`` steps at a time, sets the judged robots aside
(their carry as it stood) and, when few enough are left, continues with the rest in a batch a
``shrink``-th of the size, padded by copies of a live robot whose results are dropped; the
sizes are fixed in advance (``B``, ``B / shrink``, ...) so that a rollout compiles once per
size. At the end the carries are put back in their first order and the episodes summarised
as :func:`mbn.world.rollout.rollout` does.

What changes against the whole rollout: the statistics of a judged robot stop where it was
set aside (its distance, stall fraction over the whole trial, final pose, passes after the
J-th), and nothing else: a robot's steps are the same computation whatever batch it runs in.
Under noise the draws of a step are made for the whole batch (a robot's share depends on its
place in it), so the batch is never compacted there: the rollout only ends early once every
robot is judged.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array, lax
from jax.typing import ArrayLike

from mbn.errors import MbnInputError
from mbn.host import put
from mbn.world.engine import World
from mbn.world.rollout import (
    Carry,
    Controller,
    RolloutConfig,
    RolloutResult,
    cast_world,
    count_robot_steps,
    finish,
    is_shared,
    make_scene,
    one_step,
    start_carry,
)
from mbn.world.stats import JunctionLog

__all__ = [
    "CHUNK_STEPS",
    "FLOOR",
    "SHRINK",
    "batch_sizes",
    "judged_passes",
    "run_rollout_until_judged",
]

#: Steps between two looks at which robots are judged (10 s at the robot's 0.1 s step).
CHUNK_STEPS = 100
#: Each smaller batch is this fraction of the one before (one compilation per size; 16 judged
#: a seed's controllers on 300 generated mazes fastest, compilation included, of 4, 8 and 16:
#: ``benchmarks/README.md``, "judging.py").
SHRINK = 16
#: No batch smaller than this is made (the last robots run on in a batch of at least it).
FLOOR = 32


def batch_sizes(b: int, shrink: int = SHRINK, floor: int = FLOOR) -> list[int]:
    """The batch sizes a rollout of ``b`` robots may run at: ``b``, then ``ceil(b / shrink)``,
    and so on while at least ``floor`` (each size is one more compilation; a batch of a few
    dozen robots costs little more per step than one of a few)."""
    if b < 1 or shrink < 2 or floor < 1:
        raise MbnInputError(
            f"batch_sizes needs b >= 1, shrink >= 2 and floor >= 1, got {b}, {shrink}, {floor}"
        )
    sizes = [b]
    while sizes[-1] > 1 and -(-sizes[-1] // shrink) >= floor:
        sizes.append(-(-sizes[-1] // shrink))
    return sizes


def judged_passes(log: JunctionLog, after_tile: np.ndarray) -> np.ndarray:
    """Each robot's junction passes that count for its verdict so far: its passes kept in the
    log, only those with a tile in force where ``after_tile`` (a trial judged from its first
    tile on, ``initial`` none); a robot whose log is full counts as many as it keeps, since no
    later pass is recorded."""
    passes = np.asarray(log.passes)
    kept = np.asarray(log.tile).shape[1]
    made = np.arange(kept)[None, :] < np.minimum(passes, kept)[:, None]
    with_tile = (made & (np.asarray(log.tile) > 0)).sum(1)
    counted = np.where(after_tile, with_tile, np.minimum(passes, kept))
    return np.where(passes >= kept, np.maximum(counted, kept), counted)


def _advance(
    world: World,
    controller: Controller,
    carry: Carry,
    maze_index: Array,
    config: RolloutConfig,
    junctions: Array | None,
    key: Array | None,
    start: Array,
    stop: Array,
) -> Carry:
    scene = make_scene(world, controller, carry.ctrl, maze_index, config, junctions, key)
    return lax.fori_loop(start, stop, lambda s, c: one_step(scene, c, s)[0], carry)


def _start(
    world: World,
    controller: Controller,
    controller_state: Any,
    poses: Array,
    maze_index: Array,
    config: RolloutConfig,
    junctions: Array | None,
    key: Array | None,
) -> Carry:
    scene = make_scene(world, controller, controller_state, maze_index, config, junctions, key)
    return start_carry(scene, poses, controller_state)


def _finish(
    world: World,
    controller: Controller,
    carry: Carry,
    maze_index: Array,
    config: RolloutConfig,
    junctions: Array | None,
    key: Array | None,
) -> Any:
    scene = make_scene(world, controller, carry.ctrl, maze_index, config, junctions, key)
    return finish(scene, carry)


def _take(tree: Any, rows: np.ndarray) -> Any:
    """The rows ``rows`` of every batched leaf of a host ``tree`` (its :class:`Shared` parts as
    they are)."""
    return jax.tree.map(lambda a: a if is_shared(a) else a[rows], tree, is_leaf=is_shared)


def _device(tree: Any) -> Any:
    return jax.tree.map(lambda a: a if is_shared(a) else put(a), tree, is_leaf=is_shared)


_compiled_start = jax.jit(_start, static_argnames=("controller", "config"))
_compiled_advance = jax.jit(_advance, static_argnames=("controller", "config"))
_compiled_finish = jax.jit(_finish, static_argnames=("controller", "config"))


def _host(tree: Any) -> Any:
    return jax.tree.map(lambda a: a if is_shared(a) else np.asarray(a), tree, is_leaf=is_shared)


def _join(parts: list[Any], order: np.ndarray) -> Any:
    """Host carries of disjoint robots joined and put back in their first order (``order``:
    each joined row's place in it)."""
    back = np.argsort(order, kind="stable")

    def one(*leaves: Any) -> Any:
        if is_shared(leaves[0]):
            return leaves[0]
        return put(np.concatenate([np.asarray(x) for x in leaves], 0)[back])

    return jax.tree.map(one, *parts, is_leaf=is_shared)


def run_rollout_until_judged(
    world: World,
    controller: Controller,
    controller_state: Any,
    poses: ArrayLike,
    maze_index: ArrayLike,
    config: RolloutConfig,
    *,
    judged: ArrayLike,
    after_tile: ArrayLike | None = None,
    junctions: Array | None = None,
    key: Array | None = None,
    chunk: int | None = None,
    shrink: int | None = None,
    floor: int | None = None,
    judged_when: Callable[[JunctionLog, np.ndarray], np.ndarray] = judged_passes,
) -> RolloutResult:
    """:func:`mbn.world.rollout.run_rollout` for trials judged on their first ``judged (B,)``
    junction passes (those with a tile in force where ``after_tile (B,)``): a robot stops once
    it has made them (see the module). No trajectory is recorded (``config.record_every`` must
    be 0). Counts the robot-steps it runs. Returns the statistics in the robots' order and
    their controller states where each stopped. ``chunk``, ``shrink``, ``floor``: default
    :data:`CHUNK_STEPS`, :data:`SHRINK`, :data:`FLOOR` (:func:`batch_sizes`)."""
    chunk = CHUNK_STEPS if chunk is None else chunk
    if config.record_every:
        raise MbnInputError("run_rollout_until_judged records no trajectory: record_every 0")
    if config.noise.enabled and key is None:
        raise MbnInputError("noise is on: pass a PRNG key")
    if chunk < 1:
        raise MbnInputError(f"chunk must be >= 1, got {chunk}")
    host_poses = np.asarray(poses)
    b = host_poses.shape[0]
    index = np.asarray(maze_index, np.int32)
    if host_poses.shape != (b, 3) or index.shape != (b,):
        raise MbnInputError(
            f"poses must be (B, 3) and maze_index (B,), got {host_poses.shape} and {index.shape}"
        )
    need = np.broadcast_to(np.asarray(judged, np.int64), (b,))
    tiles = np.broadcast_to(np.asarray(False if after_tile is None else after_tile, bool), (b,))
    dtype = jnp.asarray(poses).dtype
    world = cast_world(world, dtype)  # the poses' precision, once
    compact = not config.noise.enabled
    sizes = batch_sizes(b, SHRINK if shrink is None else shrink, FLOOR if floor is None else floor)
    carry = _compiled_start(
        world, controller, controller_state, jnp.asarray(poses), put(index), config, junctions, key
    )
    ids = np.arange(b)  # each row's robot
    live = np.ones(b, bool)  # rows that are robots still running (not padding, not judged)
    rows_index = put(index)
    parts: list[Any] = []
    order: list[np.ndarray] = []
    step = 0
    while step < config.steps:
        stop = min(config.steps, step + chunk)
        carry = _compiled_advance(
            world, controller, carry, rows_index, config, junctions, key, step, stop
        )
        count_robot_steps(len(ids) * (stop - step))
        step = stop
        if step >= config.steps:
            break
        done = judged_when(carry.junctions, tiles[ids]) >= need[ids]
        if not compact:
            if (done | ~live).all():
                break
            continue
        now = live & done
        if not now.any():
            continue
        rows = np.flatnonzero(now)
        host = _host(carry)
        parts.append(_take(host, rows))
        order.append(ids[rows])
        live &= ~done
        left = np.flatnonzero(live)
        if not len(left):
            carry = None
            break
        size = min(s for s in sizes if s >= len(left))
        if size < len(ids):
            keep = np.concatenate([left, np.full(size - len(left), left[0])])
            carry = _device(_take(host, keep))
            ids, index_rows = ids[keep], index[ids[keep]]
            live = np.arange(size) < len(left)
            rows_index = put(index_rows)
    if carry is not None:
        rows = np.flatnonzero(live)
        parts.append(_take(_host(carry), rows))
        order.append(ids[rows])
    whole = _join(parts, np.concatenate(order))
    stats = _compiled_finish(world, controller, whole, put(index), config, junctions, key)
    return RolloutResult(stats=stats, trajectory=None, controller_state=whole.ctrl)
