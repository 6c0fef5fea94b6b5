"""Tests of mbn.networks.structured: the interpreter simulated by its blocks is the dense
interpreter, field for field and step for step, in every mode the experiment runs it."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbn.controllers import InterpreterControllerSpec, make_controller
from mbn.errors import MbnInputError
from mbn.networks.ctrnn import euler_steps, make_ctrnn, max_stable_dt, vector_field
from mbn.networks.emulation import piecewise_constant_inputs
from mbn.networks.multiplier import load_default
from mbn.networks.programmable import (
    Connection,
    Programmable,
    all_connections,
    build_interpreter,
    differing_connections,
    run,
    run_network,
)
from mbn.networks.structured import CHUNK, block_euler_steps, block_field, from_interpreter
from mbn.paper import published_lf, published_rf
from mbn.world.engine import compile_mazes
from mbn.world.mazes.builtin import crossroad
from mbn.world.rollout import RolloutConfig, rollout


def _genome_connections(bound: float = 20.0) -> list[Programmable]:
    """The follower genome's 12 connections: W (3 x 3) and WE on the diagonal."""
    conns = [Connection("W", i, j) for i in range(3) for j in range(3)]
    conns += [Connection("WE", k, k) for k in range(3)]
    return [Programmable(c, -bound, bound) for c in conns]


def _random_follower(seed: int):
    rng = np.random.default_rng(seed)
    return make_ctrnn(rng.uniform(-20, 20, (3, 3)), np.diag(rng.uniform(-20, 20, 3)), 0.5)


@pytest.fixture(scope="session")
def full():
    """A fully programmable interpreter (the genome's 12 connections, 6-neuron multipliers)."""
    net = _random_follower(0)
    return net, build_interpreter(net, _genome_connections(), load_default(6))


def test_the_blocks_are_the_dense_networks_connections(full):
    _, interp = full
    blocks = interp.blocks()
    assert blocks.num_neurons == interp.num_neurons == 3 + 12 * 6
    assert blocks.num_inputs == interp.net.num_inputs == 3 + 12
    assert blocks.x1_neuron == (0, 1, 2) * 3 + (-1,) * 3
    assert blocks.x1_input == (-1,) * 9 + (0, 1, 2)
    assert blocks.target == (0, 0, 0, 1, 1, 1, 2, 2, 2, 0, 1, 2)
    np.testing.assert_allclose(np.asarray(blocks.out_weight), 40.0)
    np.testing.assert_allclose(np.asarray(blocks.core.W), -20.0)  # the direct weights: min


@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_block_field_equals_the_dense_field(seed):
    net = _random_follower(seed)
    interp = build_interpreter(net, all_connections(net, bound=20.0), load_default(6))
    rng = np.random.default_rng(seed)
    y = jnp.asarray(rng.normal(0, 3, (7, interp.num_neurons)))
    u = jnp.asarray(rng.uniform(0, 1, (7, interp.net.num_inputs)))
    dense = vector_field(interp.net, y, u)
    blocks = block_field(interp.blocks(), y, u)
    scale = float(jnp.max(jnp.abs(dense)))
    assert float(jnp.max(jnp.abs(dense - blocks))) <= 1e-12 * max(scale, 1.0)


@pytest.mark.parametrize("batch", [1, pytest.param(5, marks=pytest.mark.slow), 2 * CHUNK])
def test_batched_steps_equal_the_dense_steps(full, batch):
    """Mapped over a batch with the network held (neuron-major, cut into chunks for a large
    batch, the logistic as tanh), the steps are the dense network's to round-off (float64)."""
    _, interp = full
    rng = np.random.default_rng(batch)
    y = jnp.asarray(rng.normal(0, 2, (batch, interp.num_neurons)))
    u = jnp.asarray(rng.uniform(0, 1, (batch, interp.net.num_inputs)))
    blocks = interp.blocks()
    dense = jax.vmap(lambda a, b: euler_steps(interp.net, a, b, 0.005, 20))(y, u)
    mine = jax.vmap(lambda a, b: block_euler_steps(blocks, a, b, 0.005, 20))(y, u)
    np.testing.assert_allclose(np.asarray(mine), np.asarray(dense), rtol=0, atol=1e-10)
    one = block_euler_steps(blocks, y[0], u[0], 0.005, 20)  # unbatched: the plain field
    np.testing.assert_allclose(np.asarray(one), np.asarray(dense[0]), rtol=0, atol=1e-10)


@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_exact_mode_through_the_blocks_equals_the_network(seed):
    """The structured path with exact products retraces the network it is programmed with, to
    1e-6 (float64), for a network other than the one it was built from."""
    built_from, emulated = _random_follower(seed), _random_follower(seed + 1)
    interp = build_interpreter(built_from, _genome_connections(), load_default(6))
    data = piecewise_constant_inputs(jax.random.key(seed), 8, 1000, 100, 3)
    dt = min(0.005, 0.5 * max_stable_dt(emulated))
    y0 = jnp.zeros((data.shape[1], 3))
    ref = run_network(emulated, y0, data, dt)
    program = interp.program_of(emulated)
    emu = run(interp, y0, data, program, dt, exact=True, simulation="blocks")
    assert float(jnp.max(jnp.abs(emu - ref))) <= 1e-6


def test_trained_multipliers_through_the_blocks_equal_the_dense_run():
    rf, lf = published_rf(), published_lf()
    interp = build_interpreter(rf, differing_connections(rf, lf), load_default(6))
    data = piecewise_constant_inputs(jax.random.key(3), 4, 400, 100, 3)
    y0 = jnp.zeros((4, 3))
    program = interp.program_of(lf)
    dense = run(interp, y0, data, program, 0.005, method="euler")
    blocks = run(interp, y0, data, program, 0.005, method="euler", simulation="blocks")
    np.testing.assert_allclose(np.asarray(blocks), np.asarray(dense), rtol=0, atol=1e-9)
    with pytest.raises(MbnInputError, match="simulation"):
        run(interp, y0, data, program, 0.005, simulation="sparse")


@pytest.mark.slow
def test_a_controller_file_simulated_by_blocks_drives_the_robot_as_the_dense_one(full):
    """``simulation = "blocks"`` in an interpreter file: the same trajectories in the robot."""
    net, interp = full
    programs = {"self": np.asarray(interp.program_of(net), float).tolist()}
    dense = InterpreterControllerSpec(interpreter=interp, programs=programs)
    blocks = dataclasses.replace(dense, simulation="blocks")
    mazes = [crossroad("LSR")]
    world = compile_mazes(mazes)
    poses = jnp.asarray(np.tile(mazes[0].starts[0], (4, 1)))
    poses = poses.at[:, 0].add(jnp.linspace(-0.1, 0.1, 4))
    out = {}
    for name, spec in (("dense", dense), ("blocks", blocks)):
        loaded = make_controller(spec, "self", check_stability=False)
        config = RolloutConfig(steps=60, sensors=loaded.sensors)
        result = rollout(
            world, loaded.controller, loaded.initial_state(4), poses, jnp.zeros(4, int), config
        )
        out[name] = np.asarray(result.stats.final_pose)
    np.testing.assert_allclose(out["blocks"], out["dense"], rtol=0, atol=1e-6)


def test_simulation_is_checked_and_recorded_in_the_file(full, tmp_path):
    from mbn.controllers import read_controller_spec, save_controller

    net, interp = full
    programs = {"self": np.asarray(interp.program_of(net), float).tolist()}
    with pytest.raises(MbnInputError, match="simulation must be one of dense, blocks"):
        InterpreterControllerSpec(interpreter=interp, programs=programs, simulation="sparse")
    path = tmp_path / "im.json"
    save_controller(path, InterpreterControllerSpec(interp, programs, simulation="blocks"))
    assert read_controller_spec(path).simulation == "blocks"
    save_controller(path, InterpreterControllerSpec(interp, programs))
    assert "simulation" not in path.read_text()  # the default is not written: old files hold


def test_a_dense_network_with_stray_connections_is_refused(full):
    _, interp = full
    W = np.asarray(interp.net.W).copy()
    W[5, 40] = 0.3  # between two multiplier blocks
    net = interp.net.replace(W=W)
    with pytest.raises(MbnInputError, match="outside its multiplier blocks"):
        from_interpreter(net, 3, 3, 6, interp.mul_output)
