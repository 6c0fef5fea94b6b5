"""Batched, jitted robot episodes: many controllers x start poses x mazes in one ``lax.scan``.

One robot step (default 100 ms, as Stage's ``interval_sim``), written once in
:mod:`mbn.world.step` (which the Gymnasium environment shares) plus the episode's bookkeeping of
:mod:`mbn.world.stats`:

1. sense at the current pose, every sensor of the config's :attr:`RolloutConfig.senses` (one
   :class:`~mbn.world.senses.Senses`): the sonars of :class:`~mbn.world.sensors.SensorConfig`
   (exact rays, optional Gaussian noise), the camera (when configured), the tile under the body
   (the last tile driven over stays "in force"), and the registered sensors the config names
   (:attr:`RolloutConfig.extra_sensors`, read into :attr:`Observation.extra`);
2. the controller maps ``(controller_state, observation)`` to ``(controller_state, (v, w))``; it
   integrates its own network with as many sub-steps as it needs;
3. the command gets optional Gaussian noise (and the episode's wheel bias) and is clipped to the
   P3DX limits; the pose moves by forward Euler with the heading at the start of the step (in
   the episode's scaled maze, if the noise scales it: :func:`mbn.world.step.draw_episode`);
4. a move that would make the body overlap a wall is undone and counted as a stall (Stage's rule);
5. junctions: entering and leaving a decision cell of a grid maze records a junction pass, the exit
   taken and the exits the right- and left-hand rules take there.

The steps run in one ``lax.scan`` over a :class:`Carry`; the step is pipelined (see
:func:`one_step`). The controller is written for ONE robot; the rollout vmaps it over the batch,
so its state may be any pytree (weights included, so that a batch of genomes is just a batch of
states). A part of the state every robot of the batch shares — the weights of a fixed-weight
interpreter, say — is wrapped in :class:`Shared` and held once instead of once per robot: the
controller then multiplies a batch of states by one matrix instead of a batch of matrices
(:func:`map_controller`).
"""

from __future__ import annotations

import dataclasses
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array, lax
from jax.typing import ArrayLike

from mbn.errors import MbnInputError
from mbn.host import put
from mbn.world.engine import CameraConfig, MazeConstants, World, maze_constants
from mbn.world.robot import SONAR_MAX_RANGE
from mbn.world.senses import BUILT_IN_CHANNELS, Senses
from mbn.world.sensors import NoiseConfig, SensorConfig, normalize, paper_inputs
from mbn.world.stats import (
    EXIT_NAMES,
    EpisodeStats,
    JunctionLog,
    Tally,
    count_move,
    count_sensing,
    episode_stats,
    junction_arrays,
    junction_cell,
    junction_constants,
    log_junctions,
    start_junctions,
    start_tally,
)
from mbn.world.step import (
    NO_EPISODE,
    Episode,
    Place,
    Sensed,
    applied_speeds,
    draw_episode,
    locate,
    move,
    sense,
    undo_stalled,
)

__all__ = [
    "EXIT_NAMES",
    "EpisodeStats",
    "Observation",
    "RolloutConfig",
    "RolloutResult",
    "Shared",
    "Trajectory",
    "cast_world",
    "concatenate_states",
    "count_robot_steps",
    "episode_batch",
    "input_reach",
    "is_shared",
    "junction_arrays",
    "make_scene",
    "map_controller",
    "own_tally",
    "robot_steps",
    "rollout",
    "run_rollout",
    "strip_shared",
    "tally_of",
]

Controller = Callable[[Any, "Observation"], tuple[Any, tuple[Array, Array]]]

_steps_lock = threading.Lock()
#: The process's tally; a thread may count on a tally of its own (:func:`own_tally`).
_steps_done = [0]
_tally = threading.local()


def _current() -> list[int]:
    return getattr(_tally, "counter", _steps_done)


def count_robot_steps(n: int) -> None:
    """Add ``n`` robot-steps (robots x steps of a rollout) to this thread's tally (the
    process's, unless the thread counts on its own, :func:`own_tally`): the host code that
    launches a compiled rollout counts it here (a traced rollout cannot), so that a run can
    report the robot-steps per second each stage reached."""
    counter = _current()
    with _steps_lock:
        counter[0] += int(n)


def robot_steps() -> int:
    """Robot-steps counted so far on this thread's tally (:func:`count_robot_steps`)."""
    counter = _current()
    with _steps_lock:
        return counter[0]


def own_tally(counter: list[int] | None = None) -> list[int]:
    """Make this thread count robot-steps on ``counter`` (a one-element list; a fresh one when
    ``None``) instead of the process's tally, and return it: seeds run in threads of one
    process (``mbn sweep --batched``) each count their own, and a thread that works for another
    (a pool's, evaluating part of its population) counts on that one's (:func:`tally_of`)."""
    _tally.counter = [0] if counter is None else counter
    return _tally.counter


def tally_of() -> list[int]:
    """This thread's tally, to hand to the threads that work for it (:func:`own_tally`)."""
    return _current()


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Shared:
    """A part of a batched controller state that every robot of the batch shares, without a
    batch axis (e.g. ``CTRNNState(Shared(net), y)`` with ``y`` of shape ``(B, n)``).

    The rollout maps the controller over the batch with the shared part held
    (:func:`map_controller`); the controller itself sees the plain value and must return it
    unchanged. Shared parts are not recorded in trajectories (:func:`strip_shared`).
    """

    value: Any


def is_shared(x: Any) -> bool:
    """Whether ``x`` is a :class:`Shared` part of a controller state (``is_leaf`` of the tree
    maps that keep shared parts whole)."""
    return isinstance(x, Shared)


def _unshare(tree: Any) -> Any:
    return jax.tree.map(lambda x: x.value if is_shared(x) else x, tree, is_leaf=is_shared)


def _reshare(like: Any, tree: Any) -> Any:
    return jax.tree.map(
        lambda a, b: Shared(b) if is_shared(a) else b, like, tree, is_leaf=is_shared
    )


def strip_shared(tree: Any) -> Any:
    """``tree`` with its :class:`Shared` parts replaced by None (what a trajectory records)."""
    return jax.tree.map(lambda x: None if is_shared(x) else x, tree, is_leaf=is_shared)


def map_controller(controller: Controller, state: Any) -> Controller:
    """``controller`` (written for one robot) mapped over a batch of states shaped like
    ``state``: batched leaves along their first axis, :class:`Shared` parts held for all."""
    axes = jax.tree.map(lambda x: None if is_shared(x) else 0, state, is_leaf=is_shared)

    def one(s: Any, obs: Any) -> tuple[Any, tuple[Array, Array]]:
        new, vw = controller(_unshare(s), obs)
        return _reshare(s, new), vw

    return jax.vmap(one, in_axes=(axes, 0), out_axes=(axes, 0))


def concatenate_states(states: list[Any], sizes: list[int]) -> Any:
    """Batched controller states of ``sizes[k]`` robots each, one after the other. A
    :class:`Shared` part stays shared when every state holds the same value, and is given a batch
    axis (each copy broadcast to its state's size) when they differ."""
    if len(states) != len(sizes) or not states:
        raise MbnInputError("concatenate_states: need one size per state, and a state")

    def join(*parts: Any) -> Any:
        if not is_shared(parts[0]):
            return _host_concatenate(parts)
        values = [p.value for p in parts]
        first = jax.tree.leaves(values[0])
        if all(
            all(
                np.array_equal(np.asarray(a), np.asarray(b))
                for a, b in zip(first, jax.tree.leaves(v), strict=True)
            )
            for v in values[1:]
        ):
            return parts[0]
        return jax.tree.map(
            lambda *a: _host_concatenate(
                [
                    np.broadcast_to(np.asarray(x), (n, *np.shape(x)))
                    for x, n in zip(a, sizes, strict=True)
                ]
            ),
            *values,
        )

    return jax.tree.map(join, *states, is_leaf=is_shared)


def _host_concatenate(parts: Any) -> Array:
    """Arrays joined along their first axis on the host and put on the device as one: the same
    values as ``jnp.concatenate``, without an eager program compiled for each set of shapes (a
    PRNG key array, which NumPy cannot hold, is joined by JAX)."""
    if any(jax.dtypes.issubdtype(jnp.result_type(p), jax.dtypes.prng_key) for p in parts):
        return jnp.concatenate(parts, 0)
    return put(np.concatenate([np.asarray(p) for p in parts], 0))


class Observation(NamedTuple):
    """What a controller sees at one step (for one robot; batched inside the rollout).

    ``ranges``: the configured sonars (metres); ``S``: their normalised values; ``inputs``: the
    paper's I1..I3 (eq. 3; zeros when the paper's 10 sonars are not all cast); ``camera``: colours
    of the nearest tile in view (0 none, 1 to 6); ``blobs``: blobs in view; ``tile``: colours of the
    last tile driven over (0 none yet); ``stalled``: whether the previous move was undone;
    ``t``: time (s); ``key``: this robot's PRNG key for the step, for a controller's own noise
    (neurons, program lines: :class:`~mbn.world.sensors.NoiseConfig`), None when the rollout's
    noise has no controller channel on; ``extra``: the channels of the sensors of one's own that
    the rollout reads (:attr:`RolloutConfig.extra_sensors`), by name (empty without them; None
    in an observation made by hand).
    """

    ranges: Array
    S: Array
    inputs: Array
    camera: Array
    blobs: Array
    tile: Array
    stalled: Array
    t: Array
    key: Array | None = None
    extra: dict[str, Array] | None = None


@dataclass(frozen=True)
class RolloutConfig:
    """Settings of a rollout.

    ``steps`` robot steps of ``dt`` seconds; ``camera`` None switches the camera off (it then
    reads 0); ``record_every`` > 0 records a trajectory sample every that many steps (the first
    sample is the start); ``max_junctions`` junction passes are kept per episode (all are counted).
    ``sonar_reach`` (metres) casts the sonars only that far: a wall within it reads exactly as
    without it, one beyond reads either its distance or the 5 m miss (None: the whole 5 m). Set
    it where nothing reads a range beyond it (:func:`input_reach`): the rays are most of a
    follower's robot-step (``docs/speed.md``). ``extra_sensors``: registered sensors
    (:func:`mbn.world.senses.register_sensor`) read after the sonars, camera and tile, whose
    channels reach the controller in :attr:`Observation.extra`. What a step senses is all one
    value, :attr:`senses`.
    """

    steps: int = 200
    dt: float = 0.1
    sensors: SensorConfig = field(default_factory=SensorConfig)
    camera: CameraConfig | None = None
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    record_every: int = 0
    record_controller: bool = False
    max_junctions: int = 8
    sonar_reach: float | None = None
    extra_sensors: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.sonar_reach is not None and not (0.0 < self.sonar_reach <= SONAR_MAX_RANGE):
            raise MbnInputError(
                f"sonar_reach must be in (0, {SONAR_MAX_RANGE}] m or None, got {self.sonar_reach!r}"
            )
        if not (isinstance(self.steps, int) and self.steps >= 1):
            raise MbnInputError(f"steps must be an integer >= 1, got {self.steps!r}")
        if not (self.dt > 0 and math.isfinite(self.dt)):
            raise MbnInputError(f"dt must be > 0, got {self.dt!r}")
        if self.record_every < 0:
            raise MbnInputError(f"record_every must be >= 0, got {self.record_every!r}")
        if self.max_junctions < 1:
            raise MbnInputError(f"max_junctions must be >= 1, got {self.max_junctions!r}")
        object.__setattr__(self, "extra_sensors", tuple(self.extra_sensors))
        _ = self.senses  # an unknown extra sensor is refused here, not while tracing

    @property
    def senses(self) -> Senses:
        """What a step senses (:meth:`mbn.world.senses.Senses.build`): the sonars of
        :attr:`sensors` cast :attr:`sonar_reach` far, the camera, the sensing channels of the
        noise, and the :attr:`extra_sensors`."""
        return Senses.build(
            self.sensors, self.camera, self.noise, self.sonar_reach, self.extra_sensors
        )


def input_reach(sensors: SensorConfig, noise: NoiseConfig) -> float | None:
    """The :attr:`RolloutConfig.sonar_reach` that changes nothing a controller reading the
    normalised sonars (``Observation.S``, ``inputs``) sees, nor a statistic clipped at the
    sensors' ``far`` (``EpisodeStats.min_range / far``, ``S_mean``): ``far`` when S saturates
    there (proximity or distance) and the ranges get no Gaussian noise (a far wall's noisy range
    could then fall inside ``far``); None otherwise. Ranges beyond ``far`` (``Observation.ranges``,
    ``EpisodeStats.range_mean``, a trajectory's ``ranges``) may then read the 5 m miss."""
    if sensors.normalization == "metres" or noise.sonar_std > 0:
        return None
    return float(sensors.far)


class Trajectory(NamedTuple):
    """Samples every ``record_every`` steps: ``t (n,)``; per robot ``pose (B, n, 3)`` (before the
    step's move), ``ranges (B, n, k)``, ``camera``, ``blobs``, ``tile``, ``v``, ``w`` (applied),
    ``stalled``, and ``controller`` (the controller state pytree, if recorded, without its
    :class:`Shared` parts)."""

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


# ---------------------------------------------------------------------------------------------
# the scan
#
# The step is pipelined: everything expensive (sonar rays, collision test, camera) is computed for
# the candidate pose at the END of a step and carried; the next step first resolves the move (keep
# the candidate, or undo it if it collides). The expensive results thus have one consumer (the
# loop carry), so the compiler does not duplicate them into every use. Sensing is a pure function
# of the place, so without noise this reads exactly what sensing after the resolution would; with
# noise, a robot whose move is undone keeps the noisy readings of the place it stayed at.


class Carry(NamedTuple):
    """The rollout's loop state ``(B, ...)`` between two steps.

    ``prev``: where the robots are before the pending move and what they sensed there; ``cand``:
    where the pending move would take them and what they would sense there; ``stalled``: whether
    the pending move collides (it is then undone); ``v``, ``w``: its speeds after noise and limits
    (m/s, rad/s); ``ctrl``: the controller states; ``tile``: the tile in force; ``tally``,
    ``junctions``: the episode's bookkeeping (:mod:`mbn.world.stats`).
    """

    prev: Sensed
    cand: Sensed
    stalled: Array
    v: Array
    w: Array
    ctrl: Any
    tile: Array
    tally: Tally
    junctions: JunctionLog


@dataclass(frozen=True)
class Scene:
    """What every step of one rollout shares: the world (in the poses' precision), each robot's
    maze ``maze_index (B,)`` and its constants ``mc`` (and as the junction log reads them,
    ``junction_mc``: :func:`mbn.world.stats.junction_constants`), the junction tables, the
    settings, the controller (vmapped over the batch), the noise key (None without noise) and
    what each robot's episode drew once at its start (:func:`mbn.world.step.draw_episode`: the
    maze's scale, the wheels' bias; none without those channels)."""

    world: World
    mc: MazeConstants
    junction_mc: MazeConstants
    maze_index: Array
    junctions: Array
    config: RolloutConfig
    controller: Controller
    key: Array | None
    episode: Episode = NO_EPISODE


def junction_cells(scene: Scene, place: Place) -> tuple[Array, Array]:
    """The cells of ``place`` that the junction log records (:func:`mbn.world.stats.
    junction_cell`)."""
    return junction_cell(scene.world, scene.maze_index, place.pose, place.ci, place.cj)


def step_key_of(key: Array | None, noise: NoiseConfig, step: ArrayLike) -> Array | None:
    """The noise key of step ``step``: ``key`` folded with it, None without noise."""
    if key is None or not noise.enabled:
        return None
    return jax.random.fold_in(key, step)


def step_key(scene: Scene, step: Array) -> Array | None:
    """The noise key of step ``step`` (the rollout's key folded with it), None without noise."""
    return step_key_of(scene.key, scene.config.noise, step)


def sense_at(scene: Scene, place: Place, step: Array) -> Sensed:
    """What robots at ``place`` sense (the config's :attr:`RolloutConfig.senses`), with step
    ``step``'s noise."""
    senses = scene.config.senses
    reading = sense(scene.world, scene.mc, scene.maze_index, place, senses, step_key(scene, step))
    return Sensed(place, reading)


def settle(scene: Scene, carry: Carry) -> tuple[Sensed, Tally]:
    """Make the pending move (or undo it if it collides) and count it."""
    here = undo_stalled(carry.stalled, carry.prev, carry.cand)
    v, w = applied_speeds(carry.stalled, carry.v, carry.w)
    return here, count_move(carry.tally, carry.stalled, v, w, scene.config.dt)


def observe(scene: Scene, here: Sensed, tile: Array, stalled: Array, step: Array) -> Observation:
    """The controllers' :class:`Observation` at ``here`` and step ``step``."""
    sensors = scene.config.sensors
    ranges = here.reading.ranges
    b = ranges.shape[0]
    S = normalize(ranges, sensors)
    paper_pos = sensors.paper_positions
    if paper_pos is not None:
        inputs = paper_inputs(S[:, list(paper_pos)])
    else:
        inputs = jnp.zeros((b, 3), ranges.dtype)
    t = jnp.broadcast_to(step.astype(ranges.dtype) * scene.config.dt, (b,))
    key = step_key(scene, step)
    robot_keys = None
    if key is not None and scene.config.noise.controller_enabled:
        robot_keys = jax.random.split(jax.random.fold_in(key, 5), b)  # one per robot
    extra = {c: v for c, v in here.reading.items() if c not in BUILT_IN_CHANNELS}
    return Observation(
        ranges,
        S,
        inputs,
        here.reading.camera,
        here.reading.blobs,
        tile,
        stalled,
        t,
        robot_keys,
        extra,
    )


def one_step(scene: Scene, carry: Carry, step: Array) -> tuple[Carry, tuple[Any, ...]]:
    """Step ``step`` of the scan, pipelined: settle the pending move (:func:`settle`: the robot
    is at the candidate place, or back where it was if the move stalled, and what it senses there
    was sensed when the move was made); the controllers choose ``(v, w)`` from that
    :class:`Observation`; :func:`mbn.world.step.move` gives the next candidate place and whether
    it collides, and :func:`mbn.world.step.sense` what the robots would sense there (with this
    step's noise). So sensing and the collision test happen once per step, at the candidate, and
    a robot whose move is undone keeps its readings (noise included).

    Returns the new carry and the step's record: pose before the move ``(B, 3)``, ranges, camera,
    blobs, tile, v, w (after the limits), stalled (the previous move), and the controller state
    when recorded.
    """
    step = jnp.asarray(step, jnp.int32)
    cfg = scene.config
    here, tally = settle(scene, carry)
    under = here.reading.under
    tile = jnp.where(under > 0, under, carry.tile)
    obs = observe(scene, here, tile, carry.stalled, step)
    ctrl, (v_cmd, w_cmd) = scene.controller(carry.ctrl, obs)
    pose = here.place.pose
    moved = move(
        scene.world,
        scene.mc,
        pose,
        v_cmd,
        w_cmd,
        cfg.dt,
        cfg.noise,
        step_key(scene, step),
        scene.episode,
    )
    cand = sense_at(scene, moved.place, step)
    junctions = log_junctions(
        carry.junctions,
        scene.junctions,
        scene.junction_mc,
        junction_cells(scene, carry.prev.place),
        junction_cells(scene, here.place),
        tile,
        step,
        tally.n_stall,
    )
    new = Carry(
        prev=here,
        cand=cand,
        stalled=moved.stalled,
        v=moved.v,
        w=moved.w,
        ctrl=ctrl,
        tile=tile,
        tally=count_sensing(tally, obs.ranges, obs.S),
        junctions=junctions,
    )
    record: tuple[Any, ...] = (
        pose,
        obs.ranges,
        obs.camera,
        obs.blobs,
        tile,
        moved.v,
        moved.w,
        carry.stalled,
    )
    if cfg.record_controller:
        record = (*record, strip_shared(carry.ctrl))
    return new, record


def start_carry(scene: Scene, poses: Array, controller_state: Any) -> Carry:
    """The carry before step 0: robots at ``poses (B, 3)``, no move pending."""
    b, dtype = poses.shape[0], poses.dtype
    start = sense_at(scene, locate(scene.world, scene.mc, poses, scene.episode), jnp.asarray(-1))
    return Carry(
        prev=start,
        cand=start,
        stalled=jnp.zeros((b,), bool),
        v=jnp.zeros((b,), dtype),
        w=jnp.zeros((b,), dtype),
        ctrl=controller_state,
        tile=jnp.zeros((b,), jnp.int32),
        tally=start_tally(b, len(scene.config.sensors.sonars), dtype, SONAR_MAX_RANGE),
        junctions=start_junctions(b, scene.config.max_junctions),
    )


def run_steps(scene: Scene, carry: Carry) -> tuple[Carry, Trajectory | None]:
    """All ``config.steps`` steps from ``carry``, recording every ``config.record_every``."""
    config = scene.config
    dtype = carry.v.dtype
    body = partial(one_step, scene)

    def quiet(cr: Carry, s: Array) -> tuple[Carry, None]:
        return body(cr, s)[0], None

    steps = config.steps
    every = config.record_every
    if every <= 0:
        carry, _ = lax.scan(quiet, carry, jnp.arange(steps))
        return carry, None
    n_rec = steps // every

    def chunk(carry: Carry, c: Array) -> tuple[Carry, tuple[Any, ...]]:
        carry, rec = body(carry, c * every)
        if every > 1:
            carry, _ = lax.scan(quiet, carry, c * every + jnp.arange(1, every))
        return carry, rec

    carry, recs = lax.scan(chunk, carry, jnp.arange(n_rec))
    rest = steps - n_rec * every
    if rest:
        carry, _ = lax.scan(quiet, carry, n_rec * every + jnp.arange(rest))
    swap = lambda a: jnp.swapaxes(a, 0, 1)  # noqa: E731
    ctrl_rec = jax.tree.map(swap, recs[8]) if config.record_controller else None
    trajectory = Trajectory(
        t=jnp.arange(n_rec, dtype=dtype) * every * config.dt,
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
    return carry, trajectory


def finish(scene: Scene, carry: Carry) -> EpisodeStats:
    """Settle the last pending move and summarise the episodes."""
    final, tally = settle(scene, carry)
    steps = scene.config.steps
    junctions = log_junctions(
        carry.junctions,
        scene.junctions,
        scene.junction_mc,
        junction_cells(scene, carry.prev.place),
        junction_cells(scene, final.place),
        carry.tile,
        jnp.asarray(steps, jnp.int32),
        tally.n_stall,
    )
    return episode_stats(tally, junctions, final.place.pose, carry.tile, steps)


def cast_world(world: World, dtype: Any) -> World:
    """``world`` with its geometry in ``dtype``: the poses' precision (float32 or float64)."""
    return dataclasses.replace(
        world,
        origin=world.origin.astype(dtype),
        cell=world.cell.astype(dtype),
        tiles=world.tiles.astype(dtype),
    )


def make_scene(
    world: World,
    controller: Controller,
    controller_state: Any,
    maze_index: Array,
    config: RolloutConfig,
    junctions: Array | None,
    key: Array | None,
    dtype: Any = None,
) -> Scene:
    """The :class:`Scene` of the robots in ``world`` (its geometry cast to ``dtype``, default
    the world's own), each in its maze ``maze_index (B,)``, run by ``controller`` (mapped over
    states shaped like ``controller_state``); the episode draws
    (:func:`mbn.world.step.draw_episode`) come from the start's key."""
    if dtype is not None:
        world = cast_world(world, dtype)
    if junctions is None:
        junctions = jnp.full((world.n_junction_rows, 4, 2), -1, jnp.int8)
    mc = maze_constants(world, maze_index)
    # drawn once per episode: the start's key (step -1) folded with 7 and 8
    b = maze_index.shape[0]
    episode = draw_episode(
        config.noise, step_key_of(key, config.noise, jnp.asarray(-1)), b, world.origin.dtype
    )
    return Scene(
        world=world,
        mc=mc,
        junction_mc=junction_constants(world, mc, maze_index),
        maze_index=maze_index,
        junctions=junctions,
        config=config,
        controller=map_controller(controller, controller_state),
        key=key,
        episode=episode,
    )


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
    """Run a batch of episodes (not jitted here: wrap it in :func:`jax.jit` with ``world``,
    ``controller`` and ``config`` closed over).

    Args:
        world: compiled mazes (:func:`mbn.world.engine.compile_mazes`).
        controller: ``(state, observation) -> (state, (v, w))`` for one robot.
        controller_state: initial states, a pytree whose leaves have the batch as leading axis,
            except its :class:`Shared` parts (held once for the whole batch).
        poses: start poses ``(B, 3)``.
        maze_index: ``(B,)`` index of each robot's maze in ``world``.
        config: steps, step size, sensors, camera, noise, recording.
        junctions: tables from :func:`junction_arrays` (None: no junction tracking).
        key: PRNG key for noise (required when noise is on).
    """
    poses = jnp.asarray(poses)
    maze_index = jnp.asarray(maze_index, jnp.int32)
    b = poses.shape[0]
    if poses.shape != (b, 3) or maze_index.shape != (b,):
        raise MbnInputError(
            f"poses must be (B, 3) and maze_index (B,), got {poses.shape} and {maze_index.shape}"
        )
    if config.noise.enabled and key is None:
        raise MbnInputError("noise is on: pass a PRNG key")
    scene = make_scene(
        world, controller, controller_state, maze_index, config, junctions, key, poses.dtype
    )
    carry, trajectory = run_steps(scene, start_carry(scene, poses, controller_state))
    return RolloutResult(
        stats=finish(scene, carry), trajectory=trajectory, controller_state=carry.ctrl
    )


_compiled_rollout = jax.jit(rollout, static_argnames=("controller", "config"))


def run_rollout(
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
    """:func:`rollout` compiled, once per process for each controller, config and array shapes:
    the world, the junction tables, the states and the poses are arguments, not constants, so
    that one program serves any mazes and networks of the same shapes. The controller and the
    config are its static arguments: give the same controller object for the same controller
    (the factories of :mod:`mbn.control` are memoized for that, :mod:`mbn.memo`). Counts its
    robot-steps (:func:`count_robot_steps`)."""
    count_robot_steps(int(np.shape(poses)[0]) * config.steps)
    return _compiled_rollout(
        world,
        controller,
        controller_state,
        poses,
        maze_index,
        config,
        junctions=junctions,
        key=key,
    )
