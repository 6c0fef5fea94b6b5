"""One robot step, written once: what the robot senses at a pose, and how a command moves it.

Both the batched rollout (:mod:`mbn.world.rollout`) and the Gymnasium environment
(:mod:`mbn.world.gym_env`) are built from these functions, so the two run the same world:

* :func:`sense`: at a :class:`Place` (a pose and the lattice window around it), the sonars
  (exact lattice rays, optional Gaussian noise clipped to [0, 5] m), the blob-finding camera (when
  configured) and the tile under the body;
* :func:`move`: the command gets optional Gaussian noise and is clipped to the P3DX's limits
  (:func:`command`); the pose moves by forward Euler with the heading at the start of the step
  (:func:`mbn.world.robot.integrate_pose`); the body at the new pose is tested against the walls.
  A move whose body would overlap a wall is marked ``stalled``; :func:`undo_stalled` then keeps
  the robot where it was (Stage's rule) and :func:`applied_speeds` reads 0 for its speeds.

Everything is a pure JAX function of explicit arguments over a flat batch ``(B, ...)`` of robots,
each in the maze ``maze_index`` of a compiled :class:`~mbn.world.engine.World` (its constants
``mc`` from :func:`~mbn.world.engine.maze_constants`). Lengths in metres, angles in radians,
speeds in m/s and rad/s, ``dt`` in seconds. Noise keys are one key per step: :func:`sense` folds
in 0, :func:`command` folds in 1.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple, TypeVar
from typing import cast as typed

import jax
import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from mbn.errors import MbnInputError
from mbn.world.engine import (
    CameraConfig,
    MazeConstants,
    World,
    cast,
    collides_cells,
    see_tiles,
    tile_under,
    window_words,
)
from mbn.world.geometry import sonar_rays
from mbn.world.mazes.model import TILE_COLORS
from mbn.world.robot import (
    SONAR_MAX_RANGE,
    SONAR_POSES,
    clip_command,
    integrate_pose,
)
from mbn.world.sensors import ALL_SONARS, NoiseConfig

__all__ = [
    "NO_NOISE",
    "Move",
    "Place",
    "Reading",
    "Sensed",
    "applied_speeds",
    "camera_noise",
    "command",
    "locate",
    "move",
    "overlaps",
    "sense",
    "undo_stalled",
]

#: Noise switched off (the default of every function here).
NO_NOISE = NoiseConfig()

T = TypeVar("T")


class Place(NamedTuple):
    """Where robots are: ``pose (B, 3)`` = (x, y, theta) and the lattice cell holding (x, y) with
    its packed window of the cells around it (:func:`mbn.world.engine.window_words`):
    ``words (B, n_words)`` uint32, cell indices ``ci``, ``cj (B,)`` int32. On the engine's segment
    path the cell is a culling cell and ``words (B, 1)`` its table row (int32)."""

    pose: Array
    words: Array
    ci: Array
    cj: Array


class Reading(NamedTuple):
    """What robots sense at a place: ``ranges (B, k)`` the sonars asked for (metres, in the order
    asked for); ``camera (B,)`` the colours (0 none, 1, 2) of the nearest tile in view and
    ``blobs (B,)`` the blobs in view (both 0 with the camera off); ``under (B,)`` the colours of
    the tile under the middle of the body (0 none)."""

    ranges: Array
    camera: Array
    blobs: Array
    under: Array


class Sensed(NamedTuple):
    """A place and what the robots sense there."""

    place: Place
    reading: Reading


class Move(NamedTuple):
    """A move: ``place`` the pose it leads to (the candidate, whether or not it collides);
    ``stalled (B,)`` whether the body there overlaps a wall, so that the move is undone;
    ``v``, ``w (B,)`` the commands after noise and the speed limits (m/s, rad/s)."""

    place: Place
    stalled: Array
    v: Array
    w: Array


def locate(world: World, mc: MazeConstants, pose: Array) -> Place:
    """The :class:`Place` of robots at ``pose (B, 3)``."""
    words, ci, cj = window_words(world, mc, pose[:, 0], pose[:, 1])
    return Place(pose, words, ci, cj)


def overlaps(world: World, mc: MazeConstants, place: Place) -> Array:
    """Whether the body at ``place`` overlaps a wall ``(B,)`` (touching is not overlapping)."""
    return collides_cells(world, mc, place.words, place.ci, place.cj, place.pose)


def sense(
    world: World,
    mc: MazeConstants,
    maze_index: Array,
    place: Place,
    sonars: Sequence[int] = ALL_SONARS,
    camera: CameraConfig | None = None,
    noise: NoiseConfig = NO_NOISE,
    key: Array | None = None,
    reach: float | None = None,
) -> Reading:
    """What robots at ``place`` sense.

    Args:
        world: compiled mazes, in the precision of ``place.pose``.
        mc: the robots' maze constants ``(B, ...)``.
        maze_index: ``(B,)`` index of each robot's maze in ``world``.
        place: where the robots are (:func:`locate`).
        sonars: Stage indices (0..15) of the sonars to cast, in reading order.
        camera: the blob finder's settings; None switches it off (it then reads 0).
        noise: the sonar and camera channels of :class:`NoiseConfig`: ``sonar_std`` (Gaussian,
            metres, clipped to [0, 5] m), ``sonar_dropout`` (a reading returns 5 m),
            ``camera_miss`` and ``camera_false`` (the nearest tile reads one colour less or
            one more, at most 3).
        key: this step's PRNG key (required when one of them is on); folded with 0 (ranges),
            2 (dropouts) and 3 (camera).
        reach: cast the sonars only this far (metres; :func:`mbn.world.engine.cast`): a wall
            within it reads exactly, one beyond reads its distance or the 5 m miss. None: the
            sonars' whole range.

    Returns:
        The :class:`Reading`: ranges ``(B, k)`` in the precision of the pose, the rest int32.
    """
    pose = place.pose
    origins, angles = sonar_rays(pose, SONAR_POSES[list(sonars)])
    ranges = cast(
        world,
        mc,
        place.words,
        place.ci,
        place.cj,
        origins[..., 0],
        origins[..., 1],
        angles,
        reach=reach,
    )
    sensing = (noise.sonar_std, noise.sonar_dropout, noise.camera_miss, noise.camera_false)
    if any(level > 0 for level in sensing) and key is None:
        raise MbnInputError("sensor noise is on: pass a PRNG key")
    key = typed(Array, key)  # set wherever a channel below is on
    if noise.sonar_std > 0:
        nk = jax.random.fold_in(key, 0)
        ranges = jnp.clip(
            ranges + noise.sonar_std * jax.random.normal(nk, ranges.shape, ranges.dtype),
            0.0,
            SONAR_MAX_RANGE,
        )
    if noise.sonar_dropout > 0:
        lost = jax.random.bernoulli(jax.random.fold_in(key, 2), noise.sonar_dropout, ranges.shape)
        ranges = jnp.where(lost, jnp.asarray(SONAR_MAX_RANGE, ranges.dtype), ranges)
    if camera is not None:
        seen = see_tiles(world, mc, maze_index, place.words, place.ci, place.cj, pose, camera)
        nearest, blobs = seen.nearest, seen.blobs
        if noise.camera_miss > 0 or noise.camera_false > 0:
            nearest, blobs = camera_noise(nearest, blobs, noise, jax.random.fold_in(key, 3))
    else:
        nearest = blobs = jnp.zeros(pose.shape[:1], jnp.int32)
    return Reading(ranges, nearest, blobs, tile_under(world, maze_index, pose))


def camera_noise(
    nearest: Array, blobs: Array, noise: NoiseConfig, key: Array
) -> tuple[Array, Array]:
    """The blob finder's reading ``(nearest, blobs) (B,)`` with a missed blob (probability
    ``noise.camera_miss``: one colour less, where a tile is in view) or a false one
    (``noise.camera_false``: one colour more, at most 3), drawn independently per robot; a
    miss and a false blob in the same step cancel."""
    km, kf = jax.random.split(key)
    shape = nearest.shape
    miss = jax.random.bernoulli(km, noise.camera_miss, shape) & (nearest > 0)
    false = jax.random.bernoulli(kf, noise.camera_false, shape) & (nearest < max(TILE_COLORS))
    change = false.astype(nearest.dtype) - miss.astype(nearest.dtype)
    return nearest + change, jnp.maximum(blobs + change, 0)


def command(
    v_cmd: ArrayLike,
    w_cmd: ArrayLike,
    noise: NoiseConfig = NO_NOISE,
    key: Array | None = None,
) -> tuple[Array, Array]:
    """The speeds ``(v, w)`` ``(B,)`` applied for commands ``v_cmd``, ``w_cmd (B,)``: optional
    relative Gaussian noise (``noise.wheel_std``: ``v (1 + e_v)``, ``w (1 + e_w)``; ``key``,
    this step's key, folded with 4), then absolute (``noise.v_std`` m/s, ``noise.w_std`` rad/s;
    folded with 1), then clipped to the P3DX's limits (:func:`mbn.world.robot.clip_command`)."""
    v_cmd, w_cmd = jnp.asarray(v_cmd), jnp.asarray(w_cmd)
    if (noise.v_std > 0 or noise.w_std > 0 or noise.wheel_std > 0) and key is None:
        raise MbnInputError("command noise is on: pass a PRNG key")
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
) -> Move:
    """Robots at ``pose (B, 3)`` commanded ``(v_cmd, w_cmd) (B,)`` for ``dt`` seconds.

    The commands (cast to the pose's precision) go through :func:`command`; the pose moves by
    forward Euler with the heading at the start of the step; the body at the new pose is tested
    against the walls. The returned :class:`Move` holds the new pose even where it collides: keep
    the robot where it was with :func:`undo_stalled`.
    """
    dtype = pose.dtype
    v, w = command(jnp.asarray(v_cmd, dtype), jnp.asarray(w_cmd, dtype), noise, key)
    place = locate(world, mc, integrate_pose(pose, v, w, dt))
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
