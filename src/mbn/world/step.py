"""One robot step, written once: what the robot senses at a pose, and how a command moves it.

Both the batched rollout (:mod:`mbn.world.rollout`) and the Gymnasium environment
(:mod:`mbn.world.gym_env`) are built from these functions, so the two run the same world:

* :func:`sense`: at a :class:`Place` (a pose and the lattice window around it), every sensor of
  a :class:`~mbn.world.senses.Senses` (one value: the sonars and their reach, the camera, the
  sensing noise, the sensors of one's own), read in one place into one
  :class:`~mbn.world.senses.Reading`: the sonars (exact lattice rays, optional Gaussian noise
  clipped to [0, 5] m), the blob-finding camera (when configured), the tile under the body, then
  any registered sensor the senses name (:mod:`mbn.world.senses`);
* :func:`move`: the command gets optional Gaussian noise and the episode's wheel bias and is
  clipped to the P3DX's limits (:func:`command`); the pose moves by forward Euler with the heading
  at the start of the step (:func:`mbn.world.robot.integrate_pose`; in a maze scaled by ``s`` a
  metre driven is ``1 / s`` of the compiled maze's); the body at the new pose is tested against
  the walls. A move whose body would overlap a wall is marked ``stalled``; :func:`undo_stalled`
  then keeps the robot where it was (Stage's rule) and :func:`applied_speeds` reads 0 for its
  speeds.

Everything is a pure JAX function of explicit arguments over a flat batch ``(B, ...)`` of robots,
each in the maze ``maze_index`` of a compiled :class:`~mbn.world.engine.World` (its constants
``mc`` from :func:`~mbn.world.engine.maze_constants`). Lengths in metres, angles in radians,
speeds in m/s and rad/s, ``dt`` in seconds. Noise keys are one key per step: :func:`sense` hands
it to every sensor (the sonars fold in 0, 2 and 6, the camera 3), :func:`command` folds in 4 and 1.
What an episode draws once (:func:`draw_episode`: the maze's scale, the wheels' bias; folds 7 and
8 of the episode's key) is an :class:`Episode`, given to :func:`locate` and :func:`move`.
"""

from __future__ import annotations

from typing import NamedTuple, TypeVar
from typing import cast as typed

import jax
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike, DTypeLike

from mbn.errors import MbnInputError
from mbn.world.engine import MazeConstants, World, collides_cells, window_words
from mbn.world.robot import WHEEL_BASE, clip_command, integrate_pose
from mbn.world.senses import Place, Reading, Senses, camera_noise
from mbn.world.sensors import NoiseConfig

__all__ = [
    "ALL_SENSES",
    "NO_EPISODE",
    "NO_NOISE",
    "Episode",
    "Move",
    "Place",
    "Reading",
    "Sensed",
    "Senses",
    "applied_speeds",
    "camera_noise",
    "command",
    "draw_episode",
    "locate",
    "move",
    "overlaps",
    "sense",
    "undo_stalled",
]

#: Noise switched off (the default of every function here).
NO_NOISE = NoiseConfig()
#: The senses :func:`sense` reads by default: the 16 sonars, no camera, no noise.
ALL_SENSES = Senses()

T = TypeVar("T")


class Sensed(NamedTuple):
    """A place and what the robots sense there."""

    place: Place
    reading: Reading


class Episode(NamedTuple):
    """What each robot's episode draws once (:func:`draw_episode`), ``(B,)`` or None where the
    channel is off: ``scale``, the factor its maze is scaled by (the noise's ``corridor_scale``;
    None: 1); ``bias``, its wheels' bias ``b`` (``wheel_bias``; None: 0)."""

    scale: Array | None = None
    bias: Array | None = None


#: No episode draws (the default of :func:`locate` and :func:`move`).
NO_EPISODE = Episode()


class Move(NamedTuple):
    """A move: ``place`` the pose it leads to (the candidate, whether or not it collides);
    ``stalled (B,)`` whether the body there overlaps a wall, so that the move is undone;
    ``v``, ``w (B,)`` the commands after noise and the speed limits (m/s, rad/s)."""

    place: Place
    stalled: Array
    v: Array
    w: Array


def draw_episode(noise: NoiseConfig, key: Array | None, b: int, dtype: DTypeLike) -> Episode:
    """The draws of ``b`` robots' episodes, once at their start, from the episode's ``key`` (a
    rollout's: its key folded with the start's step, -1): the maze's scale ``s`` uniform in
    ``[1 - corridor_scale, 1 + corridor_scale]`` (the key folded with 7), and the wheels' bias
    ``b ~ N(0, wheel_bias)`` clipped to [-1, 1] (a wheel at most stops; folded with 8). A
    channel that is off draws nothing and reads None."""
    if not noise.episode_enabled:
        return NO_EPISODE
    if key is None:
        raise MbnInputError("corridor_scale or wheel_bias is on: pass a PRNG key")
    scale = bias = None
    if noise.corridor_scale > 0:
        u = jax.random.uniform(jax.random.fold_in(key, 7), (b,), dtype, -1.0, 1.0)
        scale = 1.0 + noise.corridor_scale * u
    if noise.wheel_bias > 0:
        e = jax.random.normal(jax.random.fold_in(key, 8), (b,), dtype)
        bias = jnp.clip(noise.wheel_bias * e, -1.0, 1.0)
    return Episode(scale, bias)


def locate(world: World, mc: MazeConstants, pose: Array, episode: Episode = NO_EPISODE) -> Place:
    """The :class:`Place` of robots at ``pose (B, 3)`` (in the episode's scaled maze, if any:
    :attr:`Place.scale`)."""
    words, ci, cj = window_words(world, mc, pose[:, 0], pose[:, 1])
    return Place(pose, words, ci, cj, episode.scale)


def overlaps(world: World, mc: MazeConstants, place: Place) -> Array:
    """Whether the body at ``place`` overlaps a wall ``(B,)`` (touching is not overlapping)."""
    return collides_cells(world, mc, place.words, place.ci, place.cj, place.pose)


def sense(
    world: World,
    mc: MazeConstants,
    maze_index: Array,
    place: Place,
    senses: Senses = ALL_SENSES,
    key: Array | None = None,
) -> Reading:
    """What robots at ``place`` sense: every sensor of ``senses``, in its order
    (:attr:`~mbn.world.senses.Senses.names`: the sonars, the camera, the tile under the body,
    then the sensors of one's own), into one :class:`~mbn.world.senses.Reading`.

    Args:
        world: compiled mazes, in the precision of ``place.pose``.
        mc: the robots' maze constants ``(B, ...)``.
        maze_index: ``(B,)`` index of each robot's maze in ``world``.
        place: where the robots are (:func:`locate`).
        senses: what is read (:class:`~mbn.world.senses.Senses`: the sonars, in reading order,
            and their reach; the camera or None; the sensing noise; the extra sensors).
        key: this step's PRNG key (required when a sensing channel of ``senses.noise`` is on),
            handed to every sensor: the sonars fold it with 0 (ranges) and 2 (dropouts), the
            camera with 3.

    Returns:
        The :class:`~mbn.world.senses.Reading`: ``ranges (B, k)`` in the precision of the pose,
        ``camera``, ``blobs``, ``under (B,)`` int32, then every extra sensor's channels. A
        sensor whose channels are not ``(B, ...)``, take another's name or do not fill its
        width is refused.
    """
    if senses.noisy and key is None:
        raise MbnInputError("sensor noise is on: pass a PRNG key")
    b = place.pose.shape[0]
    channels: dict[str, Array] = {}
    for sensor in senses.sensors:
        read = sensor.read(world, mc, maze_index, place, senses, key)
        columns = 0
        for name, value in read.items():
            if name in channels:
                raise MbnInputError(f"sensor {sensor.name!r}: channel {name!r} is read already")
            if value.ndim not in (1, 2) or value.shape[0] != b:
                raise MbnInputError(
                    f"sensor {sensor.name!r}: channel {name!r} must be ({b},) or ({b}, n), got "
                    f"{value.shape}"
                )
            channels[name] = value
            columns += 1 if value.ndim == 1 else value.shape[1]
        if columns != sensor.width(senses):
            raise MbnInputError(
                f"sensor {sensor.name!r}: its channels fill {columns} columns, its width is "
                f"{sensor.width(senses)}"
            )
    return Reading(channels)


def command(
    v_cmd: ArrayLike,
    w_cmd: ArrayLike,
    noise: NoiseConfig = NO_NOISE,
    key: Array | None = None,
    bias: Array | None = None,
) -> tuple[Array, Array]:
    """The speeds ``(v, w)`` ``(B,)`` applied for commands ``v_cmd``, ``w_cmd (B,)``: optional
    relative Gaussian noise (``noise.wheel_std``: ``v (1 + e_v)``, ``w (1 + e_w)``; ``key``,
    this step's key, folded with 4), then absolute (``noise.v_std`` m/s, ``noise.w_std`` rad/s;
    folded with 1), then the episode's wheel bias (``noise.wheel_bias``; ``bias (B,)`` from
    :func:`draw_episode`: the left wheel's speed ``v - w L / 2`` times ``1 + b``, the right's
    ``v + w L / 2`` times ``1 - b``, so ``v - b w L / 2`` and ``w - 2 b v / L`` with ``L`` the
    wheel base, :data:`mbn.world.robot.WHEEL_BASE`), then clipped to the P3DX's limits
    (:func:`mbn.world.robot.clip_command`)."""
    v_cmd, w_cmd = jnp.asarray(v_cmd), jnp.asarray(w_cmd)
    if (noise.v_std > 0 or noise.w_std > 0 or noise.wheel_std > 0) and key is None:
        raise MbnInputError("command noise is on: pass a PRNG key")
    if (noise.wheel_bias > 0) != (bias is not None):
        raise MbnInputError(
            "wheel_bias is on: pass the episode's bias (mbn.world.step.draw_episode)"
            if noise.wheel_bias > 0
            else "a wheel bias was given but the noise's wheel_bias is 0"
        )
    key = typed(Array, key)  # set wherever a channel below is on
    if noise.wheel_std > 0:
        e = jax.random.normal(jax.random.fold_in(key, 4), (v_cmd.shape[0], 2), v_cmd.dtype)
        v_cmd = v_cmd * (1.0 + noise.wheel_std * e[:, 0])
        w_cmd = w_cmd * (1.0 + noise.wheel_std * e[:, 1])
    if noise.v_std > 0 or noise.w_std > 0:
        nk = jax.random.fold_in(key, 1)
        n = jax.random.normal(nk, (v_cmd.shape[0], 2), v_cmd.dtype)
        v_cmd = v_cmd + noise.v_std * n[:, 0]
        w_cmd = w_cmd + noise.w_std * n[:, 1]
    if bias is not None:
        b = bias.astype(v_cmd.dtype)
        v_cmd, w_cmd = v_cmd - b * w_cmd * (WHEEL_BASE / 2), w_cmd - b * v_cmd * (2 / WHEEL_BASE)
    return clip_command(v_cmd, w_cmd)


def move(
    world: World,
    mc: MazeConstants,
    pose: Array,
    v_cmd: ArrayLike,
    w_cmd: ArrayLike,
    dt: float | Array,
    noise: NoiseConfig = NO_NOISE,
    key: Array | None = None,
    episode: Episode = NO_EPISODE,
) -> Move:
    """Robots at ``pose (B, 3)`` commanded ``(v_cmd, w_cmd) (B,)`` for ``dt`` seconds.

    The commands (cast to the pose's precision) go through :func:`command` (with the
    ``episode``'s wheel bias); the pose moves by forward Euler with the heading at the start of
    the step, in a maze scaled by the episode's ``s`` at ``v / s`` of the compiled maze's metres
    per second (the turn is the same in any scale); the body at the new pose is tested against
    the walls. The returned :class:`Move` holds the new pose even where it collides (keep the
    robot where it was with :func:`undo_stalled`) and the speeds in the robot's own metres.
    """
    dtype = pose.dtype
    v, w = command(jnp.asarray(v_cmd, dtype), jnp.asarray(w_cmd, dtype), noise, key, episode.bias)
    ahead = v if episode.scale is None else v / episode.scale.astype(dtype)
    place = locate(world, mc, integrate_pose(pose, ahead, w, dt), episode)
    return Move(place, overlaps(world, mc, place), v, w)


def undo_stalled(stalled: Array, before: T, after: T) -> T:
    """``before`` where ``stalled (B,)``, else ``after``: two pytrees of the same structure whose
    leaves have the batch as leading axis (a :class:`Place`, a :class:`Sensed`, ...)."""
    return jax.tree.map(
        lambda p, c: jnp.where(stalled.reshape(-1, *([1] * (p.ndim - 1))), p, c), before, after
    )


def applied_speeds(stalled: Array, v: Array, w: Array) -> tuple[Array, Array]:
    """The speeds actually driven ``(B,)``: 0 for a move that was undone, else ``(v, w)``."""
    return jnp.where(stalled, 0.0, v), jnp.where(stalled, 0.0, w)
