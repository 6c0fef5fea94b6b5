"""One robot step (mbn.world.step): sensing, limits, kinematics, the stall rule; and the Gymnasium
environment and the rollout, both built on it, driving the same poses."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.world.engine import CameraConfig, compile_mazes, maze_constants
from mbn.world.geometry import collides, rect_segments, sonar_ranges
from mbn.world.mazes.load import load_maze
from mbn.world.mazes.model import Maze, Tile, merge_cells
from mbn.world.robot import MAX_ANGULAR_SPEED, MAX_LINEAR_SPEED, SONAR_MAX_RANGE
from mbn.world.rollout import Observation, RolloutConfig, junction_arrays, rollout
from mbn.world.senses import Senses
from mbn.world.sensors import ALL_SONARS, NoiseConfig, SensorConfig, normalize, paper_inputs
from mbn.world.step import (
    Place,
    applied_speeds,
    command,
    locate,
    move,
    overlaps,
    sense,
    undo_stalled,
)

CELL = 1.2


@pytest.fixture(scope="session")
def corridor() -> Maze:
    """A corridor along x: free for x in [1.2, 14.4], y in [1.2, 2.4]; a two-colour tile across
    it at x = 6."""
    grid = np.array([list("#############"), list("#...........#"), list("#############")])
    return Maze(
        name="corridor",
        walls=merge_cells(grid == "#", CELL),
        bounds=(0.0, 13 * CELL, 0.0, 3 * CELL),
        tiles=(Tile(6.0, 1.8, 2, heading=0.0),),
        starts=[[2.0, 1.8, 0.0], [14.15, 1.8, 0.0]],
    )


def in_maze(maze: Maze, n: int):
    """World (float64: the tests run with x64), maze constants and maze index of n robots."""
    world = compile_mazes([maze])
    mi = jnp.zeros((n,), jnp.int32)
    return world, maze_constants(world, mi), mi


# ---------------------------------------------------------------------------------------------
# move: limits, kinematics, the stall rule


def test_move_clips_commands_to_the_p3dx_limits(corridor):
    world, mc, _ = in_maze(corridor, 4)
    pose = jnp.asarray([[4.0, 1.8, 0.0]] * 4)
    v_cmd = jnp.asarray([2.0, -3.0, 0.3, 0.5])
    w_cmd = jnp.asarray([-9.0, 9.0, 0.5, -math.pi / 2])
    m = move(world, mc, pose, v_cmd, w_cmd, 0.1)
    # the P3DX's limits: 0.5 m/s and 90 degrees/s
    np.testing.assert_array_equal(m.v, [0.5, -0.5, 0.3, 0.5])
    np.testing.assert_allclose(m.w, [-math.pi / 2, math.pi / 2, 0.5, -math.pi / 2], rtol=1e-15)
    # the pose moves with the clipped speeds
    np.testing.assert_allclose(m.place.pose[0], [4.05, 1.8, -math.pi / 20], atol=1e-15)
    assert not np.any(m.stalled)


def test_kinematics_is_forward_euler_with_the_heading_at_the_start_of_the_step(corridor):
    """n steps of constant (v, w) against the closed form of forward Euler:
    x_n = x_0 + v dt sum_k cos(theta_0 + k w dt) = x_0 + v dt sin(n a/2) / sin(a/2)
    cos(theta_0 + (n-1) a/2) with a = w dt (and sin for y); the heading wraps to [-pi, pi]."""
    empty = Maze(
        "empty",
        walls=[[99.0, 100.0, 99.0, 100.0]],
        bounds=(-20, 100, -20, 100),
        outside_is_wall=False,
    )
    world, mc, _ = in_maze(empty, 2)
    v, w, dt, n = 0.4, 1.2, 0.1, 30
    pose = jnp.asarray([[1.0, 2.0, 3.0], [-1.0, 0.5, -0.7]])
    start = np.asarray(pose)
    for _ in range(n):
        m = move(world, mc, pose, jnp.full(2, v), jnp.full(2, w), dt)
        assert not np.any(m.stalled)
        pose = m.place.pose
    a = w * dt
    gain = v * dt * math.sin(n * a / 2) / math.sin(a / 2)
    mid = start[:, 2] + (n - 1) * a / 2
    expected_th = np.arctan2(np.sin(start[:, 2] + n * a), np.cos(start[:, 2] + n * a))
    np.testing.assert_allclose(pose[:, 0], start[:, 0] + gain * np.cos(mid), atol=1e-12)
    np.testing.assert_allclose(pose[:, 1], start[:, 1] + gain * np.sin(mid), atol=1e-12)
    np.testing.assert_allclose(pose[:, 2], expected_th, atol=1e-12)
    assert np.all(np.abs(pose[:, 2]) <= math.pi)  # 3.0 + 3.6 rad wrapped


def test_a_colliding_move_is_undone_and_marked_stalled(corridor):
    world, mc, _ = in_maze(corridor, 2)
    # robot 0: nose 4 cm from the east wall, driving into it; robot 1: free corridor
    pose = jnp.asarray([[14.15, 1.8, 0.0], [8.0, 1.8, 0.0]])
    before = locate(world, mc, pose)
    m = move(world, mc, pose, jnp.asarray([0.5, 0.5]), jnp.asarray([0.2, 0.2]), 0.1)
    np.testing.assert_array_equal(m.stalled, [True, False])
    # the candidate is where the body would overlap the wall (the exact polygon test agrees)
    rects = jnp.asarray(corridor.solid_rects())
    assert bool(collides(m.place.pose[0], rects)) and not bool(collides(m.place.pose[1], rects))
    np.testing.assert_array_equal(overlaps(world, mc, m.place), m.stalled)
    here = undo_stalled(m.stalled, before, m.place)
    assert isinstance(here, Place)
    np.testing.assert_array_equal(here.pose[0], pose[0])  # stayed put, with its window
    np.testing.assert_array_equal(here.words[0], before.words[0])
    np.testing.assert_array_equal(here.pose[1], m.place.pose[1])  # moved
    v, w = applied_speeds(m.stalled, m.v, m.w)
    np.testing.assert_array_equal(v, [0.0, 0.5])
    np.testing.assert_array_equal(w, [0.0, 0.2])


def test_command_noise_comes_before_the_limits_and_is_seeded():
    noise = NoiseConfig(v_std=5.0, w_std=5.0)
    v_cmd, w_cmd = jnp.full(64, 0.4), jnp.full(64, 0.0)
    v, w = command(v_cmd, w_cmd, noise, jax.random.key(3))
    assert np.all(np.abs(v) <= MAX_LINEAR_SPEED) and np.all(np.abs(w) <= MAX_ANGULAR_SPEED)
    assert np.any(v == MAX_LINEAR_SPEED) and np.any(v == -MAX_LINEAR_SPEED)  # clipped after
    v2, w2 = command(v_cmd, w_cmd, noise, jax.random.key(3))
    np.testing.assert_array_equal(v, v2)
    np.testing.assert_array_equal(w, w2)
    np.testing.assert_array_equal(command(v_cmd, w_cmd)[0], v_cmd)  # no noise: as commanded
    with pytest.raises(MbnInputError, match="key"):
        command(v_cmd, w_cmd, noise)


# ---------------------------------------------------------------------------------------------
# sense


def test_sense_reads_the_exact_geometry_the_camera_and_the_tile_under(corridor):
    world, mc, mi = in_maze(corridor, 4)
    # the two-colour tile 1.2 m ahead; on the tile; 2 m ahead looking back; 3.5 m (out of range)
    pose = jnp.asarray([[4.8, 1.8, 0.0], [6.0, 1.7, 0.3], [8.0, 1.9, 3.0], [9.5, 1.9, 3.0]])
    place = locate(world, mc, pose)
    read = jax.jit(sense, static_argnums=(4,))  # compiled once (eager, its ops took 14 s)
    r = read(world, mc, mi, place, Senses(camera=CameraConfig()))
    exact = sonar_ranges(pose, rect_segments(corridor.solid_rects()))
    np.testing.assert_allclose(r.ranges, exact, atol=1e-9)
    np.testing.assert_array_equal(r.camera, [2, 0, 2, 0])
    np.testing.assert_array_equal(r.blobs, [2, 0, 2, 0])
    np.testing.assert_array_equal(r.under, [0, 2, 0, 0])
    # a subset of sonars reads the same rays, in the order asked for; no camera reads 0
    sub = read(world, mc, mi, place, Senses(sonars=(8, 0, 15)))
    np.testing.assert_array_equal(sub.ranges, r.ranges[:, [8, 0, 15]])
    np.testing.assert_array_equal(sub.camera, [0, 0, 0, 0])
    np.testing.assert_array_equal(sub.blobs, [0, 0, 0, 0])


def test_sonar_noise_is_seeded_and_clipped_to_the_range(corridor):
    world, mc, mi = in_maze(corridor, 2)
    place = locate(world, mc, jnp.asarray([[4.0, 1.8, 0.0], [8.0, 1.5, 1.0]]))
    clean = sense(world, mc, mi, place).ranges
    noise = NoiseConfig(sonar_std=3.0)
    a = sense(world, mc, mi, place, Senses(noise=noise), jax.random.key(1)).ranges
    b = sense(world, mc, mi, place, Senses(noise=noise), jax.random.key(1)).ranges
    c = sense(world, mc, mi, place, Senses(noise=noise), jax.random.key(2)).ranges
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c) and not np.array_equal(a, clean)
    assert np.all((a >= 0.0) & (a <= SONAR_MAX_RANGE)) and np.any(a == SONAR_MAX_RANGE)
    with pytest.raises(MbnInputError, match="key"):
        sense(world, mc, mi, place, Senses(noise=noise))


def test_a_sonar_reach_reads_walls_within_it_exactly():
    """With ``reach``, a wall within it reads bit for bit as without; one beyond reads either
    its distance or the 5 m miss. Random poses in a crossroad (float64 here)."""
    from mbn.world.mazes.builtin import crossroad

    maze = crossroad("LSR")
    rng = np.random.default_rng(0)
    n = 400
    x0, x1, y0, y1 = maze.bounds
    pose = np.stack(
        [rng.uniform(x0, x1, n), rng.uniform(y0, y1, n), rng.uniform(-math.pi, math.pi, n)], -1
    )
    world, mc, mi = in_maze(maze, n)
    free = ~np.asarray(overlaps(world, mc, locate(world, mc, jnp.asarray(pose))))
    pose = jnp.asarray(pose[free])
    world, mc, mi = in_maze(maze, len(pose))
    place = locate(world, mc, pose)
    full = np.asarray(sense(world, mc, mi, place, Senses(sonars=ALL_SONARS)).ranges)
    for reach in (0.5, 2.0):
        short = np.asarray(sense(world, mc, mi, place, Senses(reach=reach)).ranges)
        within = full <= reach
        assert within.any() and (~within).any()
        np.testing.assert_array_equal(short[within], full[within])
        beyond = short[~within]
        assert np.all((beyond == full[~within]) | (beyond == SONAR_MAX_RANGE))
    assert np.any(short[~within] == SONAR_MAX_RANGE) and np.any(full[~within] < SONAR_MAX_RANGE)


# ---------------------------------------------------------------------------------------------
# the Gymnasium environment and the rollout: one step, the same poses

SENSORS = SensorConfig(sonars=ALL_SONARS)  # the Gym's 16 sonars, in Stage's order
PAPER = jnp.asarray(SENSORS.paper_positions)


def centring(state, obs):
    """A float32 controller for one robot: centre between the side walls (eq. 3's I1 - I2),
    slow down as the front closes in; v exceeds the limit on a clear front and w off-centre, so
    the limits are exercised. It reads only what the Gym's observation carries."""
    S = normalize(obs.ranges.astype(jnp.float32), SENSORS)
    right, left, front = paper_inputs(S[PAPER])
    v = 0.6 * (1.2 - front)
    w = 4.0 * (right - left) + 0.3 * (obs.camera > 0)
    return state + 1, (v, w)


def drive_gym(maze: Maze, start: list[float], steps: int):
    """The controller driving the Gym env: poses ``(steps + 1, 3)`` and stall flags."""
    gym_env = pytest.importorskip("mbn.world.gym_env")
    env = gym_env.PioneerMazeEnv(maze, start=start, jitter=False, max_steps=steps)
    obs, info = env.reset()
    control = jax.jit(centring)
    state = jnp.int32(0)
    poses, stalled = [info["pose"]], []
    for _ in range(steps):
        seen = Observation(
            ranges=jnp.asarray(obs[:16]),  # the Gym's float32 observation
            S=jnp.zeros(16, jnp.float32),
            inputs=jnp.zeros(3, jnp.float32),
            camera=jnp.int32(info["camera"]),
            blobs=jnp.int32(info["blobs"]),
            tile=jnp.int32(info["tile"]),
            stalled=jnp.asarray(info["stalled"]),
            t=jnp.float32(info["t"]),
        )
        state, (v, w) = control(state, seen)
        obs, _, _, _, info = env.step(np.array([float(v), float(w)]))
        poses.append(info["pose"])
        stalled.append(info["stalled"])
    env.close()
    return np.array(poses), np.array(stalled)


def drive_rollout(maze: Maze, start: list[float], steps: int, dtype):
    """The controller driving a one-robot rollout in ``dtype``: poses ``(steps + 1, 3)``, the
    stall flags of moves 0..steps-2 (the trajectory's ``stalled[k]`` is move k - 1's) and the
    number of stalled moves."""
    world = compile_mazes([maze])
    cfg = RolloutConfig(steps=steps, sensors=SENSORS, camera=CameraConfig(), record_every=1)
    run = jax.jit(
        lambda p: rollout(
            world,
            centring,
            jnp.zeros(1, jnp.int32),
            p,
            jnp.zeros(1, jnp.int32),
            cfg,
            junctions=junction_arrays([maze], world),
        )
    )
    out = run(jnp.asarray([start], dtype))
    poses = np.concatenate([out.trajectory.pose[0], out.stats.final_pose], 0)
    n_stalled = round(float(out.stats.stall_fraction[0]) * steps)
    return poses, np.asarray(out.trajectory.stalled[0, 1:]), n_stalled


def angle_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs((a - b + math.pi) % (2 * math.pi) - math.pi)


CASES = [
    # corridor, off-centre: the tile, then the east wall (38 stalled moves at the end)
    ("corridor", [2.0, 1.7, 0.1], 300),
    # fig4 start 0: junctions, turns and tiles
    ("fig4", 0, 200),
]


@pytest.fixture(params=CASES, ids=[c[0] for c in CASES])
def episode(request, corridor):
    """(maze, start pose, steps) of a case."""
    name, start, steps = request.param
    maze = corridor if name == "corridor" else load_maze(name)
    pose = maze.starts[start] if isinstance(start, int) else start
    return maze, [float(x) for x in pose], steps


def test_gym_env_and_float64_rollout_drive_the_same_poses(episode):
    """Gym: world and pose in float64 (x64 is on, so compile_mazes makes a float64 world),
    observation float32 (its Box); rollout: float64 poses, so a float64 world. The controller
    computes in float32 on both sides from float32 ranges (it rounds the rollout's itself), so
    it sees the same numbers. What may still differ is how XLA compiles the one step into two
    programs (the Gym's jitted step, the rollout's scan), e.g. multiply-adds fused or not: at
    most a few float64 ulp (< 1e-14 m at 16 m) per step, far below 1e-12 over these episodes
    (the two agree bitwise here). Equal poses at every step also mean equal stall decisions."""
    maze, start, steps = episode
    gym_poses, gym_stalled = drive_gym(maze, start, steps)
    poses, stalled, n_stalled = drive_rollout(maze, start, steps, jnp.float64)
    np.testing.assert_allclose(poses[:, :2], gym_poses[:, :2], rtol=0, atol=1e-12)
    assert np.max(angle_diff(poses[:, 2], gym_poses[:, 2])) <= 1e-12
    np.testing.assert_array_equal(stalled, gym_stalled[:-1])
    assert n_stalled == int(gym_stalled.sum())
    if maze.name == "corridor":
        assert n_stalled > 0  # the stall rule is part of what is compared


@pytest.mark.slow  # float64 above in CI
def test_gym_env_and_float32_rollout_drive_the_same_poses(episode):
    """Gym as above (float64 world and pose); rollout in float32, as the experiments run it.
    float32 keeps 24 bits: a coordinate below 16 m is rounded to 2^-20 m (about 1e-6 m) at
    every step, and a reading likewise. Over n steps these roundings add up to at most about
    n x 1e-6 (3e-4 m, and 3e-4 rad through the sonar feedback of the centring controller, which
    is stable and so does not amplify them) even if they never cancel; the differences seen are
    about 2e-5 m and 1.3e-5 rad. The stall decisions are the same (no move here ends within
    1e-6 m of a wall)."""
    maze, start, steps = episode
    gym_poses, gym_stalled = drive_gym(maze, start, steps)
    poses, stalled, n_stalled = drive_rollout(maze, start, steps, jnp.float32)
    tol = steps * 2.0**-20
    np.testing.assert_allclose(poses[:, :2], gym_poses[:, :2], rtol=0, atol=tol)
    assert np.max(angle_diff(poses[:, 2], gym_poses[:, 2])) <= tol
    np.testing.assert_array_equal(stalled, gym_stalled[:-1])
    assert n_stalled == int(gym_stalled.sum())
