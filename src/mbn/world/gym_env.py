"""A Gymnasium environment: one Pioneer 3DX in a maze, driven by speed commands.

``PioneerMazeEnv`` (registered as ``mbn/PioneerMaze-v0``; ``docs/gym.md``) runs the
same world as :mod:`mbn.world.rollout`, for one robot at a time: a stateful shell over the robot
step that the rollout runs too (:mod:`mbn.world.step`: the engine's exact sonar rays, body-wall
collision and blob-finding camera, the speed limits and the kinematics) under one jitted step.

* **Action** ``(v, w)``: linear (m/s) and angular (rad/s) speed, a ``Box`` of
  ``[-0.5, 0.5] x [-pi/2, pi/2]``; commands beyond it are clipped to the P3DX's limits as Stage
  does. With ``normalized_actions=True`` the action space is ``[-1, 1]^2`` instead, scaled to
  those limits (what most reinforcement-learning libraries expect).
* **Dynamics** (one step of ``dt`` seconds, Stage's rules): forward Euler with the heading at the
  start of the step; a move that would make the body overlap a wall is undone (the robot stays
  put and ``info["stalled"]`` is True).
* **Observation**: a float32 ``Box(0, 5, (17,))``: the 16 sonar ranges (metres, Stage order
  s00..s15, 5.0 where a ray meets no wall) at the pose after the step, then the number of colour
  blobs the camera sees (capped at 5; 0 with the camera off).
* **Reward** (the paper's F_M idea per step: drive forward, straight, clear of walls)::

      r = (v / 0.5) * (1 - |w| / (pi / 2)) * min(1, d_min / 0.5)    if the move was made,
      r = -1                                                         if it was undone (stall),

  with ``v``, ``w`` the commands after clipping and ``d_min`` the shortest of the 16 ranges
  after the move. Driving backwards is penalised (``v < 0``); the reward lies in [-1, 1].
* **Episode end**: never terminated (a maze has no goal); truncated after ``max_steps`` steps.
* **Info**: ``pose`` (x, y, theta), ``stalled``, ``tile`` (colours of the last tile driven over:
  the tile in force, 0 none yet), ``camera`` (colours of the nearest tile in view, 0 none),
  ``blobs`` (uncapped), ``v``, ``w`` (applied), ``t`` (seconds since reset).
* **Reset**: at ``maze.starts[start]`` (or a pose); with ``jitter`` (default on) the pose moves
  by uniform noise of up to 0.1 m along and across the heading and 5 degrees of heading, drawn
  from the environment's ``np_random``, so ``reset(seed=...)`` is deterministic.
  ``reset(options={"start": ...})`` picks another start (index or pose) for that episode.
* **Rendering**: ``render_mode="rgb_array"`` returns an ``(H, W, 3)`` uint8 frame of the maze with
  the robot, its trail since the reset, its sonar rays and the camera's field of view
  (:class:`mbn.viz.episodes.EpisodeView`).

Gymnasium is an optional dependency (``pip install 'mbn[gym]'``); importing :mod:`mbn` or
:mod:`mbn.world` does not import it. An installed ``mbn`` registers the environment as Gymnasium
is imported (``_mbn_gymnasium``, from the path file ``mbn-gymnasium.pth``), so
``gymnasium.make("mbn/PioneerMaze-v0")`` works with no import of ``mbn``; importing this module
registers it too (``docs/gym.md``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import partial
from typing import Any, SupportsFloat

import numpy as np

try:
    import gymnasium
    from gymnasium import spaces
except ImportError as exc:  # pragma: no cover - exercised by simulating a missing gymnasium
    raise ImportError(
        "mbn.world.gym_env needs gymnasium, an optional dependency: pip install 'mbn[gym]'"
    ) from exc

import jax
import jax.numpy as jnp
from jax import Array

from mbn.errors import MbnInputError
from mbn.world.engine import CameraConfig, World, compile_mazes, maze_constants
from mbn.world.mazes.model import Maze
from mbn.world.robot import MAX_ANGULAR_SPEED, MAX_LINEAR_SPEED, SONAR_MAX_RANGE, SONAR_POSES
from mbn.world.senses import Reading, Senses
from mbn.world.step import applied_speeds, locate, move, overlaps, sense, undo_stalled

__all__ = ["ENV_ID", "MAX_BLOBS", "PioneerMazeEnv", "register"]

#: The id under which :class:`PioneerMazeEnv` is registered.
ENV_ID = "mbn/PioneerMaze-v0"
#: The blob count in the observation is capped here.
MAX_BLOBS = 5
#: Default jitter of reset poses: metres along and across the heading, degrees of heading.
DEFAULT_JITTER = (0.1, 5.0)
_DEFAULT_CAMERA = CameraConfig()
_N_SONARS = SONAR_POSES.shape[0]
_STALL_PENALTY = 1.0
_CLEARANCE = 0.5  # metres: closer than this to a wall scales the reward down


# ---------------------------------------------------------------------------------------------
# the jitted single-robot step (a batch of 1 in maze 0 of a compiled world), over mbn.world.step
#
# The world travels as an argument (a pytree whose lattice sizes are static), so every
# environment on the same maze shares one compiled step; the senses (all 16 sonars, the camera
# or none, no noise) are a static argument.


@partial(jax.jit, static_argnames=("senses",))
def _observe(world: World, senses: Senses, pose: Array) -> tuple[Array, Reading]:
    """Whether the body at ``pose (1, 3)`` overlaps a wall, and what the robot senses there."""
    mi = jnp.zeros((1,), jnp.int32)
    mc = maze_constants(world, mi)
    place = locate(world, mc, pose)
    return overlaps(world, mc, place), sense(world, mc, mi, place, senses)


@partial(jax.jit, static_argnames=("senses",))
def _step(
    world: World,
    senses: Senses,
    pose: Array,
    v_cmd: Array,
    w_cmd: Array,
    dt: Array,
) -> tuple[Array, Array, Array, Array, Reading]:
    """One step of the world's rules for the robot at ``pose (1, 3)``: the new pose (the old one
    if the move stalled), whether it stalled, the speeds driven and what the robot senses at the
    new pose."""
    mi = jnp.zeros((1,), jnp.int32)
    mc = maze_constants(world, mi)
    moved = move(world, mc, pose, v_cmd, w_cmd, dt)
    here = undo_stalled(moved.stalled, locate(world, mc, pose), moved.place)
    v, w = applied_speeds(moved.stalled, moved.v, moved.w)
    return here.pose, moved.stalled, v, w, sense(world, mc, mi, here, senses)


# ---------------------------------------------------------------------------------------------
# the environment


def _fmt_pose(pose: np.ndarray) -> str:
    return "({:.4g}, {:.4g}, {:.4g})".format(*(float(v) for v in pose))


def _load(maze: Maze | str) -> Maze:
    if isinstance(maze, Maze):
        return maze
    if isinstance(maze, str):
        from mbn.world.mazes.load import load_maze

        return load_maze(maze)
    raise MbnInputError(f"maze must be a Maze or a maze spec (str), got {type(maze).__name__}")


class PioneerMazeEnv(gymnasium.Env[np.ndarray, np.ndarray]):
    """One simulated Pioneer 3DX in a maze (see the module docstring for spaces, dynamics and
    reward).

    Args:
        maze: a :class:`~mbn.world.mazes.model.Maze`, or a spec for
            :func:`mbn.world.mazes.load.load_maze` (a built-in name or a file).
        start: index into ``maze.starts``, or a pose ``(x, y, theta)`` (radians).
        dt: the step (seconds).
        max_steps: steps before the episode is truncated.
        camera: the blob finder's settings; None switches it off (the blob count reads 0).
        jitter: True (0.1 m and 5 degrees), False, or ``(metres, degrees)``: the uniform noise
            added to the start pose at each reset.
        render_mode: None or ``"rgb_array"``.
        normalized_actions: actions in ``[-1, 1]^2``, scaled to the speed limits.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 10}  # noqa: RUF012

    def __init__(
        self,
        maze: Maze | str = "cross_LSR",
        start: int | Sequence[float] = 0,
        dt: float = 0.1,
        max_steps: int = 600,
        camera: CameraConfig | None = _DEFAULT_CAMERA,
        jitter: bool | tuple[float, float] = True,
        render_mode: str | None = None,
        normalized_actions: bool = False,
    ) -> None:
        self.maze = _load(maze)
        if not (isinstance(dt, int | float) and math.isfinite(dt) and dt > 0):
            raise MbnInputError(f"dt must be a finite number > 0, got {dt!r}")
        if isinstance(max_steps, bool) or not (isinstance(max_steps, int) and max_steps >= 1):
            raise MbnInputError(f"max_steps must be an integer >= 1, got {max_steps!r}")
        if camera is not None and not isinstance(camera, CameraConfig):
            raise MbnInputError(f"camera must be a CameraConfig or None, got {camera!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise MbnInputError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        if jitter is True:
            jitter = DEFAULT_JITTER
        elif jitter is False:
            jitter = (0.0, 0.0)
        try:
            js = tuple(float(j) for j in jitter)
        except (TypeError, ValueError):
            js = ()
        if len(js) != 2 or not all(math.isfinite(j) and j >= 0 for j in js):
            raise MbnInputError(
                f"jitter must be True, False or (metres, degrees) >= 0, got {jitter!r}"
            )
        self.jitter = (js[0], math.radians(js[1]))
        self.dt = float(dt)
        self.max_steps = max_steps
        self.camera = camera
        self.render_mode = render_mode
        self.normalized_actions = bool(normalized_actions)
        self.metadata = {**self.metadata, "render_fps": 1.0 / self.dt}

        self._world = compile_mazes([self.maze])
        self._dtype = self._world.cell.dtype  # the world's float type
        self._start = self._start_pose(start)
        if self._collides(self._start):
            raise MbnInputError(
                f"maze {self.maze.name!r}: the start pose {_fmt_pose(self._start)} puts the robot"
                " in a wall"
            )

        self.observation_space = spaces.Box(
            low=0.0, high=SONAR_MAX_RANGE, shape=(_N_SONARS + 1,), dtype=np.float32
        )
        if self.normalized_actions:
            self.action_space = spaces.Box(low=-1.0, high=1.0, shape=(2,), dtype=np.float32)
        else:
            limit = np.array([MAX_LINEAR_SPEED, MAX_ANGULAR_SPEED], dtype=np.float32)
            self.action_space = spaces.Box(low=-limit, high=limit, dtype=np.float32)

        self._pose = self._start.copy()
        self._tile = 0
        self._steps = 0
        self._ranges = np.full(_N_SONARS, SONAR_MAX_RANGE)
        self._camera_reading = 0
        self._stalled = False
        self._trail: list[np.ndarray] = []
        self._view: Any = None

    # -- helpers -------------------------------------------------------------------------------

    @property
    def _senses(self) -> Senses:
        """What the robot senses: the 16 sonars in Stage's order, the camera, no noise."""
        return Senses(camera=self.camera)

    def _start_pose(self, start: Any) -> np.ndarray:
        """A start index or pose as a pose ``(3,)``."""
        if isinstance(start, int | np.integer) and not isinstance(start, bool):
            n = len(self.maze.starts)
            if not 0 <= int(start) < n:
                raise MbnInputError(
                    f"start index {start} out of range: maze {self.maze.name!r} has {n} start"
                    f" pose{'s' if n != 1 else ''}"
                )
            return np.array(self.maze.starts[int(start)], dtype=np.float64)
        try:
            pose = np.asarray(start, dtype=np.float64)
        except (TypeError, ValueError):
            pose = np.zeros(0)
        if pose.shape != (3,) or not np.all(np.isfinite(pose)):
            raise MbnInputError(
                f"start must be an index into maze.starts or a finite pose (x, y, theta),"
                f" got {start!r}"
            )
        return pose

    def _jnp_pose(self, pose: np.ndarray) -> Array:
        return jnp.asarray(pose[None, :], dtype=self._dtype)

    def _collides(self, pose: np.ndarray) -> bool:
        hit = _observe(self._world, self._senses, self._jnp_pose(pose))[0]
        return bool(hit[0])

    def _observation(self, ranges: np.ndarray, blobs: int) -> np.ndarray:
        obs = np.empty(_N_SONARS + 1, dtype=np.float32)
        obs[:_N_SONARS] = np.clip(ranges, 0.0, SONAR_MAX_RANGE)
        obs[_N_SONARS] = min(blobs, MAX_BLOBS)
        return obs

    def _info(self, blobs: int, v: float = 0.0, w: float = 0.0) -> dict[str, Any]:
        return {
            "pose": self._pose.copy(),
            "stalled": self._stalled,
            "tile": self._tile,
            "camera": self._camera_reading,
            "blobs": blobs,
            "v": v,
            "w": w,
            "t": self._steps * self.dt,
        }

    # -- the Gymnasium API ---------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode at the start pose (``options={"start": index or pose}`` overrides
        it for this episode), jittered with the environment's ``np_random``."""
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = set(options) - {"start"}
        if unknown:
            raise MbnInputError(f"unknown reset option(s) {sorted(unknown)}; known: start")
        base = self._start_pose(options["start"]) if "start" in options else self._start
        if "start" in options and self._collides(base):
            raise MbnInputError(
                f"maze {self.maze.name!r}: the start pose {_fmt_pose(base)} puts the robot in a"
                " wall"
            )
        pose = base
        metres, radians = self.jitter
        if metres > 0 or radians > 0:
            for _ in range(20):  # redraw in the rare case that the jitter hits a wall
                along, across = self.np_random.uniform(-metres, metres, size=2)
                dth = self.np_random.uniform(-radians, radians)
                c, s = math.cos(base[2]), math.sin(base[2])
                cand = np.array(
                    [
                        base[0] + along * c - across * s,
                        base[1] + along * s + across * c,
                        math.atan2(math.sin(base[2] + dth), math.cos(base[2] + dth)),
                    ]
                )
                if not self._collides(cand):
                    pose = cand
                    break
        _, reading = jax.device_get(_observe(self._world, self._senses, self._jnp_pose(pose)))
        self._pose = pose.astype(np.float64)
        self._steps = 0
        self._stalled = False
        self._tile = int(reading.under[0])
        self._camera_reading = int(reading.camera[0])
        self._ranges = np.asarray(reading.ranges[0], dtype=np.float64)
        self._trail = [self._pose.copy()]
        blobs = int(reading.blobs[0])
        return self._observation(self._ranges, blobs), self._info(blobs)

    def step(
        self, action: np.ndarray
    ) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        """Apply ``action`` = ``(v, w)`` for ``dt`` seconds (see the module docstring)."""
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (2,) or not np.all(np.isfinite(a)):
            raise MbnInputError(f"action must be 2 finite numbers (v, w), got {action!r}")
        if self.normalized_actions:  # [-1, 1] to the limits; the step clips what lies beyond
            a = a * np.array([MAX_LINEAR_SPEED, MAX_ANGULAR_SPEED])
        new, hit, v, w, reading = jax.device_get(
            _step(
                self._world,
                self._senses,
                self._jnp_pose(self._pose),
                jnp.asarray(a[0:1], self._dtype),
                jnp.asarray(a[1:2], self._dtype),
                jnp.asarray(self.dt, self._dtype),
            )
        )
        self._steps += 1
        self._stalled = bool(hit[0])
        self._pose = np.asarray(new[0], dtype=np.float64)
        if int(reading.under[0]) > 0:
            self._tile = int(reading.under[0])
        self._camera_reading = int(reading.camera[0])
        self._ranges = np.asarray(reading.ranges[0], dtype=np.float64)
        self._trail.append(self._pose.copy())
        v_app, w_app = float(v[0]), float(w[0])
        if self._stalled:
            reward = -_STALL_PENALTY
        else:
            clear = min(1.0, float(self._ranges.min()) / _CLEARANCE)
            reward = (v_app / MAX_LINEAR_SPEED) * (1.0 - abs(w_app) / MAX_ANGULAR_SPEED) * clear
        truncated = self._steps >= self.max_steps
        n_blobs = int(reading.blobs[0])
        obs = self._observation(self._ranges, n_blobs)
        return obs, float(reward), False, truncated, self._info(n_blobs, v_app, w_app)

    def render(self) -> np.ndarray | None:
        """With ``render_mode="rgb_array"``: the current frame ``(H, W, 3)`` uint8; else None."""
        if self.render_mode != "rgb_array":
            return None
        if self._view is None:
            from mbn.viz.episodes import EpisodeView

            self._view = EpisodeView(
                self.maze,
                dpi=80.0,
                camera_fov_deg=None if self.camera is None else self.camera.fov_deg,
                camera_range=3.0 if self.camera is None else self.camera.range,
            )
        self._view.update(
            self._pose,
            trail=np.array(self._trail) if self._trail else None,
            ranges=self._ranges,
            camera=self._camera_reading if self.camera is not None else None,
            tile=self._tile,
            t=self._steps * self.dt,
            stalled=self._stalled,
        )
        frame: np.ndarray = self._view.rgb()
        return frame

    def close(self) -> None:
        """Release the rendering figure (calling it twice is harmless)."""
        self._view = None
        super().close()


def register() -> None:
    """Register :class:`PioneerMazeEnv` with Gymnasium as :data:`ENV_ID` (idempotent)."""
    if ENV_ID not in gymnasium.registry:
        gymnasium.register(id=ENV_ID, entry_point="mbn.world.gym_env:PioneerMazeEnv")


register()
