"""The noise model (docs/noise.md): each channel does what it says, at the rate it says, seeded;
off by default and then nothing changes."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.control.ctrnn import (
    CTRNNState,
    ProgrammedState,
    ctrnn_controller,
    initial_state,
    interpreter_controller,
)
from mbn.errors import MbnInputError
from mbn.experiments.crossroads import crossroad
from mbn.networks.ctrnn import make_ctrnn
from mbn.world.engine import compile_mazes, maze_constants
from mbn.world.mazes.model import Maze, Tile, merge_cells
from mbn.world.robot import SONAR_MAX_RANGE
from mbn.world.rollout import Observation, RolloutConfig, rollout
from mbn.world.senses import Senses
from mbn.world.sensors import NoiseConfig, parse_noise
from mbn.world.step import camera_noise, command, locate, sense

CELL = 1.2
N = 20_000  # draws for a rate: a binomial's std at p = 0.3 is 0.0032, the tolerances ~4 std


def corridor() -> Maze:
    grid = np.array([list("#############"), list("#...........#"), list("#############")])
    return Maze(
        name="corridor",
        walls=merge_cells(grid == "#", CELL),
        bounds=(0.0, 13 * CELL, 0.0, 3 * CELL),
        tiles=(Tile(6.0, 1.8, 2, heading=0.0),),
        starts=[[2.0, 1.8, 0.0]],
    )


def test_noise_is_off_by_default_and_each_level_is_checked():
    off = NoiseConfig()
    assert not off.enabled and not off.world_enabled and not off.controller_enabled
    assert NoiseConfig(sonar_dropout=0.01).world_enabled
    assert not NoiseConfig(sonar_dropout=0.01).controller_enabled
    assert NoiseConfig(neuron_std=0.1).controller_enabled
    assert not NoiseConfig(program_std=0.1).world_enabled
    for bad in ({"sonar_std": -0.1}, {"sonar_dropout": 1.5}, {"camera_miss": float("nan")}):
        with pytest.raises(MbnInputError, match=f"noise.{next(iter(bad))}"):
            NoiseConfig(**bad)


def test_parse_noise_inline_and_from_a_settings_file(tmp_path):
    assert parse_noise("sonar_std=0.02, wheel_std=0.05") == NoiseConfig(
        sonar_std=0.02, wheel_std=0.05
    )
    path = tmp_path / "run.toml"
    path.write_text("[run]\nseed = 1\n\n[noise]\ncamera_miss = 0.05\nsonar_dropout = 0.01\n")
    assert parse_noise(str(path)) == NoiseConfig(camera_miss=0.05, sonar_dropout=0.01)
    path.write_text("[noise]\ncamera_miss = 0.05\nsonar_drop = 0.01\n")
    with pytest.raises(MbnInputError, match=r"run.toml:3: noise.sonar_drop: unknown setting"):
        parse_noise(str(path))
    path.write_text("[run]\nseed = 1\n")
    with pytest.raises(MbnInputError, match="no \\[noise\\] table"):
        parse_noise(str(path))
    with pytest.raises(MbnInputError, match="expected KEY=VALUE"):
        parse_noise("sonar_std")
    with pytest.raises(MbnInputError, match="noise sonar_std: not a number"):
        parse_noise("sonar_std=much")


def test_sonar_dropout_returns_the_miss_at_its_rate():
    world = compile_mazes([corridor()])
    mi = jnp.zeros((N,), jnp.int32)
    mc = maze_constants(world, mi)
    place = locate(world, mc, jnp.tile(jnp.asarray([[4.0, 1.8, 0.0]]), (N, 1)))
    clean = np.asarray(sense(world, mc, mi, place).ranges)
    noisy = np.asarray(
        sense(
            world, mc, mi, place, Senses(noise=NoiseConfig(sonar_dropout=0.3)), jax.random.key(3)
        ).ranges
    )
    lost = noisy != clean
    np.testing.assert_array_equal(noisy[lost], SONAR_MAX_RANGE)  # a dropout reads the miss
    # every sonar that sees a wall within 5 m: its readings drop at the rate asked for
    near = clean[0] < SONAR_MAX_RANGE - 1e-9
    assert near.sum() >= 10
    rate = lost[:, near].mean(axis=0)
    np.testing.assert_allclose(rate, 0.3, atol=0.015)
    with pytest.raises(MbnInputError, match="key"):
        sense(world, mc, mi, place, Senses(noise=NoiseConfig(sonar_dropout=0.3)))


def test_camera_noise_misses_and_invents_blobs_at_their_rates():
    nearest = jnp.asarray(np.repeat([0, 1, 2, 3], N // 4), jnp.int32)
    blobs = nearest
    key = jax.random.key(4)
    # always: a miss takes one colour where a tile is seen; a false blob adds one, at most 3
    n, b = camera_noise(nearest, blobs, NoiseConfig(camera_miss=1.0), key)
    np.testing.assert_array_equal(np.asarray(n), np.maximum(np.asarray(nearest) - 1, 0))
    np.testing.assert_array_equal(np.asarray(b), np.asarray(n))
    n, _ = camera_noise(nearest, blobs, NoiseConfig(camera_false=1.0), key)
    np.testing.assert_array_equal(np.asarray(n), np.minimum(np.asarray(nearest) + 1, 3))
    # at a rate: the fraction changed
    n, _ = camera_noise(nearest, blobs, NoiseConfig(camera_miss=0.2), key)
    changed = np.asarray(n) != np.asarray(nearest)
    assert not changed[: N // 4].any()  # nothing in view: nothing to miss
    np.testing.assert_allclose(changed[N // 4 :].mean(), 0.2, atol=0.015)
    n, _ = camera_noise(nearest, blobs, NoiseConfig(camera_false=0.1), key)
    changed = np.asarray(n) != np.asarray(nearest)
    np.testing.assert_allclose(changed[: 3 * N // 4].mean(), 0.1, atol=0.012)
    assert not changed[3 * N // 4 :].any()  # three colours are the most


def test_wheel_noise_is_relative_to_the_command():
    v = jnp.full((N,), 0.2)
    w = jnp.concatenate([jnp.full((N // 2,), 0.4), jnp.zeros((N // 2,))])
    nv, nw = command(v, w, NoiseConfig(wheel_std=0.05), jax.random.key(5))
    ratio = np.asarray(nv) / 0.2
    np.testing.assert_allclose(ratio.mean(), 1.0, atol=0.003)
    np.testing.assert_allclose(ratio.std(), 0.05, rtol=0.05)
    np.testing.assert_allclose(np.asarray(nw)[: N // 2].std() / 0.4, 0.05, rtol=0.05)
    np.testing.assert_array_equal(np.asarray(nw)[N // 2 :], 0.0)  # no command, no noise
    with pytest.raises(MbnInputError, match="key"):
        command(v, w, NoiseConfig(wheel_std=0.05))


def _obs(key):
    z = jnp.zeros(())
    return Observation(
        ranges=jnp.zeros(10), S=jnp.zeros(10), inputs=jnp.asarray([0.2, 0.1, 0.3]),
        camera=jnp.int32(0), blobs=jnp.int32(0), tile=jnp.int32(0), stalled=jnp.bool_(False),
        t=z, key=key,
    )  # fmt: skip


def test_neuron_noise_adds_its_std_to_every_potential_per_robot_step():
    net = make_ctrnn(np.zeros((3, 3)), np.zeros((3, 3)), 0.5)
    clean = ctrnn_controller(dt=0.1, substeps=20)
    noisy = ctrnn_controller(dt=0.1, substeps=20, noise=NoiseConfig(neuron_std=0.5))
    state = initial_state(net)
    keys = jax.random.split(jax.random.key(6), 4000)
    y_clean = clean(state, _obs(None))[0].y  # at rest with zero weights: stays 0
    ys = jax.vmap(lambda k: noisy(state, _obs(k))[0].y)(keys)
    np.testing.assert_allclose(np.asarray(y_clean), 0.0)
    np.testing.assert_allclose(np.asarray(ys).std(axis=0), 0.5, rtol=0.06)
    np.testing.assert_allclose(np.asarray(ys).mean(axis=0), 0.0, atol=0.03)
    with pytest.raises(MbnInputError, match="no key"):
        noisy(state, _obs(None))


def test_program_noise_is_clipped_and_leaves_the_stored_program():
    # a probe network whose neurons 0, 1 read the two program lines: from rest, with W = 0, two
    # Euler steps of h / tau = 0.1 give y = 0.19 u, so u = y / 0.19 is the program it received
    probe = make_ctrnn(np.zeros((3, 3)), np.eye(3, 5, k=3), 0.5)
    program = jnp.asarray([0.3, 1.0])
    control = interpreter_controller(substeps=2, noise=NoiseConfig(program_std=0.1))
    keys = jax.random.split(jax.random.key(7), 4000)
    out = jax.vmap(lambda k: control(ProgrammedState(probe, jnp.zeros(3), program), _obs(k))[0])(
        keys
    )
    np.testing.assert_array_equal(np.asarray(out.program), np.tile(program, (4000, 1)))
    u = np.asarray(out.y)[:, :2] / 0.19
    np.testing.assert_allclose(u[:, 0].mean(), 0.3, atol=0.01)
    np.testing.assert_allclose(u[:, 0].std(), 0.1, rtol=0.06)
    assert u[:, 1].max() <= 1.0 + 1e-9 and u[:, 1].min() < 0.8  # clipped at 1 from above
    np.testing.assert_allclose((u[:, 1] > 1.0 - 1e-9).mean(), 0.5, atol=0.04)


@pytest.mark.slow
def test_rollout_noise_off_changes_nothing_and_on_is_seeded():
    mazes = [crossroad("SR")]
    world = compile_mazes(mazes)
    rng = np.random.default_rng(0)
    net = make_ctrnn(rng.uniform(-8, 8, (3, 3)), rng.uniform(-8, 8, (3, 3)), 0.5)
    poses = jnp.asarray(np.repeat(mazes[0].starts[:1], 2, 0))
    mi = jnp.zeros(2, jnp.int32)
    batch = CTRNNState(jax.tree.map(lambda a: jnp.stack([a, a]), net), jnp.zeros((2, 3)))

    def go(noise, key, built=None):
        ctrl = ctrnn_controller(substeps=20, noise=built)
        cfg = RolloutConfig(steps=60, noise=noise)
        return np.asarray(
            jax.jit(lambda k: rollout(world, ctrl, batch, poses, mi, cfg, key=k))(
                key
            ).stats.final_pose
        )

    plain = go(NoiseConfig(), None)
    np.testing.assert_array_equal(go(NoiseConfig(), None, NoiseConfig()), plain)
    for noise in (
        NoiseConfig(sonar_dropout=0.2, camera_miss=0.5, wheel_std=0.1),
        NoiseConfig(neuron_std=0.5),
    ):
        a = go(noise, jax.random.key(1), noise)
        np.testing.assert_array_equal(a, go(noise, jax.random.key(1), noise))
        assert not np.allclose(a, go(noise, jax.random.key(2), noise))
        assert not np.allclose(a[0], a[1])  # each robot its own noise
        assert not np.allclose(a, plain)
    with pytest.raises(MbnInputError, match="no key"):  # the controller's noise, none rolled
        go(NoiseConfig(), None, NoiseConfig(neuron_std=0.5))
