"""The envelope channels of the noise model (docs/noise.md, "The channels"): the maze's scale and
the wheels' bias drawn once per episode, the sonar's cone drawn per reading. Each changes what it
names and nothing else, is seeded, refuses bad levels in one line, and off changes nothing."""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.world.engine import CameraConfig, compile_mazes, maze_constants
from mbn.world.mazes.builtin import crossroad
from mbn.world.mazes.model import Maze, Tile, merge_cells
from mbn.world.robot import SONAR_MAX_RANGE, WHEEL_BASE
from mbn.world.rollout import EXIT_NAMES, RolloutConfig, junction_arrays, rollout
from mbn.world.senses import Senses
from mbn.world.sensors import NoiseConfig, SensorConfig, parse_noise
from mbn.world.step import command, draw_episode, locate, move, sense

CELL = 1.2
N = 4000
#: A side sonar (s00, +90 degrees, 0.136 m left of the axis) of a robot on the corridor's axis
#: reads the wall 0.6 - 0.136 m away, square on.
SIDE = 0.6 - 0.136
CHANNELS = ("corridor_scale", "sonar_cone", "wheel_bias")


def corridor() -> Maze:
    grid = np.array([list("#############"), list("#...........#"), list("#############")])
    return Maze(
        name="corridor",
        walls=merge_cells(grid == "#", CELL),
        bounds=(0.0, 13 * CELL, 0.0, 3 * CELL),
        tiles=(Tile(6.0, 1.8, 2, heading=0.0),),
        starts=[[2.0, 1.8, 0.0]],
    )


def room() -> Maze:
    """No wall within 20 m of the origin."""
    return Maze(
        "room", walls=[[100.0, 101.0, 100.0, 101.0]], bounds=(-50, 101, -50, 101),
        outside_is_wall=False,
    )  # fmt: skip


def at(world, pose, n):
    mi = jnp.zeros((n,), jnp.int32)
    mc = maze_constants(world, mi)
    return mi, mc, jnp.tile(jnp.asarray([pose], jnp.float64), (n, 1))


def constant(state, obs):
    """A controller that ignores what it senses: state = its command (2,)."""
    return state, (state[0], state[1])


def scripted(state, obs):
    """A controller replaying a command table: state = (step, table (T, 2))."""
    step, table = state
    return (step + 1, table), (table[step, 0], table[step, 1])


@functools.cache
def world_of(maze_factory):
    return compile_mazes([maze_factory()])


@functools.cache
def compiled(maze_factory, cfg):
    """The jitted rollout of constant commands in ``maze_factory()``'s maze under ``cfg``."""
    world = world_of(maze_factory)

    def go(state, poses, key):
        mi = jnp.zeros(poses.shape[0], jnp.int32)
        return rollout(world, constant, state, poses, mi, cfg, key=key)

    return jax.jit(go)


def drive(maze_factory, poses, command_vw, noise, key, steps, **config):
    """Robots at ``poses`` commanded a constant ``command_vw (B, 2)`` for ``steps`` steps."""
    cfg = RolloutConfig(steps=steps, noise=noise, record_every=1, **config)
    fn = compiled(maze_factory, cfg)
    return fn(jnp.asarray(command_vw, jnp.float64), jnp.asarray(poses, jnp.float64), key)


def episode_of(noise, key, b):
    """The draws a rollout with ``key`` makes at its start (docs/noise.md: the start's key)."""
    return draw_episode(noise, jax.random.fold_in(key, jnp.asarray(-1)), b, jnp.float64)


# ---------------------------------------------------------------------------------------------
# the settings


def test_the_channels_are_settings_off_by_default_with_their_ranges():
    off = NoiseConfig()
    for name in CHANNELS:
        assert getattr(off, name) == 0.0
        on = NoiseConfig(**{name: 0.1})
        assert on.world_enabled and on.enabled and not on.controller_enabled
    assert NoiseConfig(corridor_scale=0.1).episode_enabled
    assert NoiseConfig(wheel_bias=0.1).episode_enabled
    assert not NoiseConfig(sonar_cone=10.0).episode_enabled  # drawn per reading
    assert not off.episode_enabled
    bad = {
        "corridor_scale": (-0.1, 0.51, math.nan, math.inf),
        "sonar_cone": (-1.0, 60.5, math.nan),
        "wheel_bias": (-0.01, 0.6, math.nan),
    }
    for name, values in bad.items():
        for value in values:
            with pytest.raises(MbnInputError, match=f"^noise.{name}: ") as caught:
                NoiseConfig(**{name: value})
            assert "\n" not in str(caught.value)


def test_the_command_line_reads_the_channels_and_refuses_bad_levels_in_one_line():
    assert parse_noise("corridor_scale=0.1, sonar_cone=20, wheel_bias=0.02") == NoiseConfig(
        corridor_scale=0.1, sonar_cone=20.0, wheel_bias=0.02
    )
    for text, message in (
        ("corridor_scale=0.9", "noise corridor_scale: must be <= 0.5, got 0.9"),
        ("sonar_cone=-5", "noise sonar_cone: must be >= 0, got -5.0"),
        ("wheel_bias=1", "noise wheel_bias: must be <= 0.5, got 1.0"),
    ):
        with pytest.raises(MbnInputError) as caught:
            parse_noise(text)
        assert str(caught.value) == message


# ---------------------------------------------------------------------------------------------
# corridor_scale


def test_a_scaled_maze_scales_every_sonar_reading_and_nothing_else():
    world = world_of(corridor)
    mi, mc, pose = at(world, [4.0, 1.8, 0.0], N)
    noise = NoiseConfig(corridor_scale=0.1)
    episode = draw_episode(noise, jax.random.key(1), N, jnp.float64)
    assert episode.bias is None
    s = np.asarray(episode.scale)
    # s uniform in [0.9, 1.1]: its range filled, its mean 1 (the std of the mean is 0.0009)
    assert s.min() >= 0.9 and s.max() <= 1.1
    assert s.min() < 0.902 and s.max() > 1.098
    np.testing.assert_allclose(s.mean(), 1.0, atol=0.004)
    camera = CameraConfig()
    clean = sense(world, mc, mi, locate(world, mc, pose), Senses(camera=camera))
    scaled = sense(
        world, mc, mi, locate(world, mc, pose, episode), Senses(camera=camera, noise=noise)
    )
    r0, r = np.asarray(clean.ranges), np.asarray(scaled.ranges)
    np.testing.assert_allclose(r0[:, 0], SIDE, atol=1e-9)
    hit = r0 < SONAR_MAX_RANGE
    assert hit.all()  # every sonar sees a wall here (a miss: the next test)
    # a wall d away in the compiled maze reads s d
    np.testing.assert_allclose(r[hit], (s[:, None] * r0)[hit], rtol=1e-12)
    ratio = r[:, 0] / SIDE
    assert ratio.min() >= 0.9 - 1e-12 and ratio.max() <= 1.1 + 1e-12
    for channel in ("camera", "blobs", "under"):
        np.testing.assert_array_equal(np.asarray(scaled[channel]), np.asarray(clean[channel]))


@pytest.mark.slow
def test_a_scaled_maze_reads_a_wall_beyond_five_metres_as_the_miss():
    wall = Maze("wall", walls=[[5.0, 6.0, -3.0, 3.0]], bounds=(-2, 7, -3, 3), outside_is_wall=False)
    world = compile_mazes([wall])
    mi, mc, pose = at(world, [0.5, 0.0, 0.0], 3)
    noise = NoiseConfig(corridor_scale=0.5)
    episode = draw_episode(noise, jax.random.key(0), 3, jnp.float64)._replace(
        scale=jnp.asarray([1.0, 0.5, 1.5])
    )
    r = np.asarray(
        sense(world, mc, mi, locate(world, mc, pose, episode), Senses(noise=noise)).ranges
    )
    ahead = (5.0 - 0.5 - 0.166) / math.cos(math.radians(10.0))  # s03, 10 degrees left: 4.40 m
    np.testing.assert_allclose(r[:2, 3], [ahead, 0.5 * ahead], rtol=1e-9)
    assert r[2, 3] == SONAR_MAX_RANGE  # 1.5 x 4.40 m is beyond the sonar's 5 m
    assert r[1, 11] == SONAR_MAX_RANGE  # behind it, nothing: the miss at any scale


@pytest.mark.slow
def test_a_scaled_maze_with_a_sonar_reach_reads_every_wall_within_it_exactly():
    world = world_of(corridor)
    n = 64
    mi, mc, _ = at(world, [0.0, 0.0, 0.0], n)
    rng = np.random.default_rng(3)
    pose = jnp.asarray(
        np.stack([rng.uniform(8.0, 13.5, n), np.full(n, 1.8), rng.uniform(-3, 3, n)], 1)
    )
    noise = NoiseConfig(corridor_scale=0.5)
    episode = draw_episode(noise, jax.random.key(2), n, jnp.float64)
    place = locate(world, mc, pose, episode)
    whole = np.asarray(sense(world, mc, mi, place, Senses(noise=noise)).ranges)
    reach = np.asarray(sense(world, mc, mi, place, Senses(noise=noise, reach=1.5)).ranges)
    near = whole <= 1.5
    assert near.sum() > n
    np.testing.assert_array_equal(reach[near], whole[near])


def test_the_scale_is_drawn_once_per_episode_and_a_metre_driven_is_one_over_s():
    b, steps, v = 8, 30, 0.3
    noise = NoiseConfig(corridor_scale=0.2)
    key = jax.random.key(11)
    sensors = SensorConfig(sonars=(0, 7), normalization="metres", far=5.0)
    out = drive(corridor, [[2.0, 1.8, 0.0]] * b, [[v, 0.0]] * b, noise, key, steps, sensors=sensors)
    plain = drive(
        corridor,
        [[2.0, 1.8, 0.0]] * b,
        [[v, 0.0]] * b,
        NoiseConfig(),
        None,
        steps,
        sensors=sensors,
    )
    s = np.asarray(episode_of(noise, key, b).scale)
    assert len(np.unique(s)) == b  # each robot its own maze
    ranges = np.asarray(out.trajectory.ranges)  # (b, steps, 2): both sides, at every step
    np.testing.assert_allclose(np.asarray(plain.trajectory.ranges), SIDE, atol=1e-9)
    np.testing.assert_allclose(
        ranges, np.broadcast_to(s[:, None, None] * SIDE, ranges.shape), rtol=1e-9
    )
    # it drove v t metres of its own, v t / s of the compiled maze's, straight on
    np.testing.assert_allclose(np.asarray(out.stats.distance), v * steps * 0.1, rtol=1e-9)
    final = np.asarray(out.stats.final_pose)
    np.testing.assert_allclose(final[:, 0], 2.0 + v * steps * 0.1 / s, rtol=1e-9)
    np.testing.assert_allclose(final[:, 1:], np.asarray(plain.stats.final_pose)[:, 1:], atol=1e-12)
    again = drive(
        corridor, [[2.0, 1.8, 0.0]] * b, [[v, 0.0]] * b, noise, key, steps, sensors=sensors
    )
    np.testing.assert_array_equal(np.asarray(again.trajectory.ranges), ranges)
    other = drive(
        corridor,
        [[2.0, 1.8, 0.0]] * b,
        [[v, 0.0]] * b,
        noise,
        jax.random.key(12),
        steps,
        sensors=sensors,
    )
    assert not np.allclose(np.asarray(other.trajectory.ranges), ranges)


JUNCTION_STEPS = 150


@functools.cache
def crossroad_run(noise):
    """The crossroad LSR and its jitted rollout of command tables under ``noise``."""
    maze = crossroad("LSR")
    world = compile_mazes([maze])
    junctions = junction_arrays([maze], world)
    cfg = RolloutConfig(steps=JUNCTION_STEPS, noise=noise, record_every=1)

    def go(tables, poses, key):
        state = (jnp.zeros(tables.shape[0], jnp.int32), tables)
        mi = jnp.zeros(tables.shape[0], jnp.int32)
        return rollout(world, scripted, state, poses, mi, cfg, junctions=junctions, key=key)

    return maze, jax.jit(go)


@pytest.mark.parametrize("turn", [pytest.param("left", marks=pytest.mark.slow), "right"])
def test_junctions_are_judged_in_a_scaled_maze(turn):
    """Robots in crossroads scaled by s, driving s times as fast (0.4 s m/s for 9 s to the
    junction's centre, a quarter turn, on), follow the unscaled path in the compiled maze's
    coordinates, and their junction passes are judged the same."""
    b, steps = 6, JUNCTION_STEPS
    noise = NoiseConfig(corridor_scale=0.1)
    key = jax.random.key(5)
    maze, scaled = crossroad_run(noise)
    _, unscaled = crossroad_run(NoiseConfig())
    s = np.asarray(episode_of(noise, key, b).scale)
    table = np.zeros((steps, 2))
    table[:, 0] = 0.4
    table[90:100] = [0.0, (math.pi / 2) * (1 if turn == "left" else -1)]
    tables = jnp.asarray(np.stack([table * [[si, 1.0]] for si in s]))
    poses = jnp.asarray(np.repeat(maze.starts[:1], b, 0), jnp.float64)
    out = scaled(tables, poses, key)
    plain = unscaled(jnp.asarray(table[None]), poses[:1], None)
    np.testing.assert_allclose(
        np.asarray(out.trajectory.pose),
        np.broadcast_to(np.asarray(plain.trajectory.pose), (b, steps, 3)),
        atol=1e-9,
    )
    for stats in (out.stats, plain.stats):
        assert np.all(np.asarray(stats.n_junctions) == 1)
        assert {EXIT_NAMES[int(x)] for x in np.asarray(stats.junction_exit[:, 0])} == {turn}
        assert np.all(np.asarray(stats.stall_fraction) == 0.0)
    for name in ("junction_cell", "junction_step", "junction_exit_step", "junction_heading"):
        np.testing.assert_array_equal(
            np.asarray(getattr(out.stats, name)),
            np.broadcast_to(np.asarray(getattr(plain.stats, name)), getattr(out.stats, name).shape),
        )
    np.testing.assert_allclose(
        np.asarray(out.stats.distance), float(plain.stats.distance[0]) * s, rtol=1e-9
    )


def test_a_scale_and_the_senses_must_agree():
    world = world_of(corridor)
    mi, mc, pose = at(world, [4.0, 1.8, 0.0], 3)
    noise = NoiseConfig(corridor_scale=0.1)
    episode = draw_episode(noise, jax.random.key(0), 3, jnp.float64)
    with pytest.raises(MbnInputError, match="corridor_scale is on: locate the robots"):
        sense(world, mc, mi, locate(world, mc, pose), Senses(noise=noise))
    with pytest.raises(MbnInputError, match="corridor_scale is 0"):
        sense(world, mc, mi, locate(world, mc, pose, episode), Senses())
    with pytest.raises(MbnInputError, match="pass a PRNG key"):
        draw_episode(noise, None, 3, jnp.float64)


# ---------------------------------------------------------------------------------------------
# sonar_cone


def test_a_cone_draws_each_reading_along_a_ray_within_it():
    world = world_of(corridor)
    mi, mc, pose = at(world, [4.0, 1.8, 0.0], N)
    place = locate(world, mc, pose)
    cone = 30.0
    noise = NoiseConfig(sonar_cone=cone)
    senses = Senses(camera=CameraConfig(), noise=noise)
    clean = sense(world, mc, mi, place, Senses(camera=CameraConfig()))
    a = sense(world, mc, mi, place, senses, jax.random.key(1))
    r = np.asarray(a.ranges)
    # the side walls are square on: a ray phi off the axis reads SIDE / cos(phi), phi within
    # +-15 degrees, so every reading lies in [SIDE, SIDE / cos 15] and |phi| is uniform in [0, 15]
    for side in (0, 7):
        assert r[:, side].min() >= SIDE - 1e-9
        assert r[:, side].max() <= SIDE / math.cos(math.radians(cone / 2)) + 1e-9
        phi = np.degrees(np.arccos(np.clip(SIDE / r[:, side], -1, 1)))
        np.testing.assert_allclose(phi.mean(), cone / 4, atol=0.25)  # the mean's std is 0.07
        assert phi.max() > 0.98 * cone / 2
    assert abs(np.corrcoef(r[:, 0], r[:, 7])[0, 1]) < 0.1  # drawn per reading
    # the same key the same readings; the next step's key others
    again = sense(world, mc, mi, place, senses, jax.random.key(1))
    np.testing.assert_array_equal(np.asarray(again.ranges), r)
    other = np.asarray(sense(world, mc, mi, place, senses, jax.random.key(2)).ranges)
    assert np.all(other[:, 0] != r[:, 0])
    for channel in ("camera", "blobs", "under"):
        np.testing.assert_array_equal(np.asarray(a[channel]), np.asarray(clean[channel]))
    with pytest.raises(MbnInputError, match="key"):
        sense(world, mc, mi, place, senses)


def test_a_cone_leaves_the_other_sonar_channels_draws_as_they_were():
    world = world_of(corridor)
    mi, mc, pose = at(world, [4.0, 1.8, 0.0], N)
    place = locate(world, mc, pose)
    key = jax.random.key(4)
    drop = np.asarray(
        sense(world, mc, mi, place, Senses(noise=NoiseConfig(sonar_dropout=0.3)), key).ranges
    )
    both = np.asarray(
        sense(
            world, mc, mi, place, Senses(noise=NoiseConfig(sonar_dropout=0.3, sonar_cone=20.0)), key
        ).ranges
    )
    side = [0, 7, 8, 15]  # always see a wall within the cone: they read 5 m only when dropped
    np.testing.assert_array_equal(
        drop[:, side] == SONAR_MAX_RANGE, both[:, side] == SONAR_MAX_RANGE
    )
    kept = both[:, side] < SONAR_MAX_RANGE
    assert kept.mean() == pytest.approx(0.7, abs=0.02)
    assert np.all(both[:, side][kept] != drop[:, side][kept])


@pytest.mark.slow
def test_a_cone_varies_the_readings_per_step_and_not_the_path():
    b, steps = 4, 40
    noise = NoiseConfig(sonar_cone=20.0)
    sensors = SensorConfig(sonars=(0, 7), normalization="metres", far=5.0)
    poses, vw = [[2.0, 1.8, 0.0]] * b, [[0.2, 0.0]] * b
    out = drive(corridor, poses, vw, noise, jax.random.key(8), steps, sensors=sensors)
    plain = drive(corridor, poses, vw, NoiseConfig(), None, steps, sensors=sensors)
    np.testing.assert_array_equal(
        np.asarray(out.trajectory.pose), np.asarray(plain.trajectory.pose)
    )
    r = np.asarray(out.trajectory.ranges)
    assert r.min() >= SIDE - 1e-9 and r.max() <= SIDE / math.cos(math.radians(10.0)) + 1e-9
    assert len(np.unique(r[0, :, 0])) == steps  # a new ray every step
    assert r[:, :, 0].std() > 0.002


# ---------------------------------------------------------------------------------------------
# wheel_bias


def test_the_wheel_bias_scales_each_wheel_and_is_drawn_per_episode():
    noise = NoiseConfig(wheel_bias=0.05)
    episode = draw_episode(noise, jax.random.key(6), 20_000, jnp.float64)
    assert episode.scale is None
    bias = np.asarray(episode.bias)
    np.testing.assert_allclose(bias.std(), 0.05, rtol=0.03)
    np.testing.assert_allclose(bias.mean(), 0.0, atol=0.0015)
    v = jnp.full(bias.shape, 0.2)
    w = jnp.where(jnp.arange(bias.size) % 2 == 0, 0.4, -0.7)
    nv, nw = command(v, w, noise, None, episode.bias)
    left, right = np.asarray(nv - nw * WHEEL_BASE / 2), np.asarray(nv + nw * WHEEL_BASE / 2)
    np.testing.assert_allclose(left, (np.asarray(v - w * WHEEL_BASE / 2)) * (1 + bias), atol=1e-12)
    np.testing.assert_allclose(right, (np.asarray(v + w * WHEEL_BASE / 2)) * (1 - bias), atol=1e-12)
    wide = np.asarray(
        draw_episode(NoiseConfig(wheel_bias=0.5), jax.random.key(6), 20_000, jnp.float64).bias
    )
    assert np.abs(wide).max() == 1.0  # a wheel at most stops
    with pytest.raises(MbnInputError, match="wheel_bias is on: pass the episode's bias"):
        command(v, w, noise, None)
    with pytest.raises(MbnInputError, match="wheel_bias is 0"):
        command(v, w, NoiseConfig(), None, episode.bias)


def test_a_robot_commanded_straight_drives_the_biased_curve():
    b, steps, v, dt = 6, 100, 0.3, 0.1
    noise = NoiseConfig(wheel_bias=0.05)
    key = jax.random.key(9)
    poses = [[0.0, 0.0, 0.5]] * b
    out = drive(room, poses, [[v, 0.0]] * b, noise, key, steps)
    plain = drive(room, poses, [[v, 0.0]] * b, NoiseConfig(), None, steps)
    bias = np.asarray(episode_of(noise, key, b).bias)
    assert np.abs(bias).max() > 0.02
    # the wheels (1 + b) and (1 - b) of v: v itself, and a turn of -2 b v / L every second
    np.testing.assert_allclose(np.asarray(out.trajectory.v), v, rtol=1e-12)
    w = -2 * bias * v / WHEEL_BASE
    np.testing.assert_allclose(
        np.asarray(out.trajectory.w), np.broadcast_to(w[:, None], (b, steps)), rtol=1e-12
    )
    pose = np.asarray(out.trajectory.pose)
    turned = np.angle(np.exp(1j * np.diff(pose[:, :, 2], axis=1)))
    np.testing.assert_allclose(turned, np.broadcast_to(w[:, None] * dt, turned.shape), rtol=1e-9)
    # the path's curvature, from the circle through its first, middle and last samples: -2 b / L
    # (forward Euler's polygon lies on a circle whose radius differs by (w dt)^2 / 24, < 1e-5)
    p1, p2, p3 = pose[:, 0, :2], pose[:, steps // 2, :2], pose[:, -1, :2]
    cross = (p2 - p1)[:, 0] * (p3 - p1)[:, 1] - (p2 - p1)[:, 1] * (p3 - p1)[:, 0]
    sides = (
        np.linalg.norm(p2 - p1, axis=1)
        * np.linalg.norm(p3 - p2, axis=1)
        * np.linalg.norm(p3 - p1, axis=1)
    )
    curvature = 2 * cross / sides
    np.testing.assert_allclose(curvature, -2 * bias / WHEEL_BASE, rtol=1e-3, atol=1e-6)
    # nothing else: where it starts it senses what it sensed, and it drives as far
    np.testing.assert_array_equal(
        np.asarray(out.trajectory.ranges[:, 0]), np.asarray(plain.trajectory.ranges[:, 0])
    )
    np.testing.assert_allclose(
        np.asarray(out.stats.distance), np.asarray(plain.stats.distance), rtol=1e-12
    )
    np.testing.assert_allclose(np.asarray(plain.trajectory.w), 0.0)
    again = drive(room, poses, [[v, 0.0]] * b, noise, key, steps)
    np.testing.assert_array_equal(
        np.asarray(again.stats.final_pose), np.asarray(out.stats.final_pose)
    )


# ---------------------------------------------------------------------------------------------
# all three


def test_off_changes_nothing_and_each_channel_is_seeded():
    b, steps = 3, 40
    poses, vw = [[2.0, 1.8, 0.0]] * b, [[0.25, 0.1]] * b

    def flat(out):
        return np.concatenate(
            [np.asarray(x).ravel() for x in jax.tree.leaves((out.stats, out.trajectory))]
        )

    plain = flat(drive(corridor, poses, vw, NoiseConfig(), None, steps))
    np.testing.assert_array_equal(
        flat(drive(corridor, poses, vw, NoiseConfig(), jax.random.key(1), steps)), plain
    )
    for name, level in (("corridor_scale", 0.1), ("sonar_cone", 20.0), ("wheel_bias", 0.05)):
        noise = NoiseConfig(**{name: level})
        a = flat(drive(corridor, poses, vw, noise, jax.random.key(1), steps))
        np.testing.assert_array_equal(
            a, flat(drive(corridor, poses, vw, noise, jax.random.key(1), steps))
        )
        assert not np.array_equal(
            a, flat(drive(corridor, poses, vw, noise, jax.random.key(2), steps))
        )
        assert not np.array_equal(a, plain)


def test_move_without_an_episode_is_the_move_it_was():
    world = world_of(corridor)
    _, mc, pose = at(world, [2.0, 1.8, 0.3], 5)
    v, w = jnp.full((5,), 0.3), jnp.full((5,), 0.2)
    a = move(world, mc, pose, v, w, 0.1)
    assert a.place.scale is None
    expected = np.asarray(pose) + np.asarray([0.03 * math.cos(0.3), 0.03 * math.sin(0.3), 0.02])
    np.testing.assert_allclose(np.asarray(a.place.pose), expected, atol=1e-12)
