"""Controllers: a reference network riding along (``shadowed``) and its motor mismatch."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.control.ctrnn import (
    CTRNNState,
    MotorMap,
    ShadowedState,
    ctrnn_controller,
    initial_state,
    shadowed,
)
from mbn.experiments.evolve import Genome
from mbn.world.engine import compile_mazes
from mbn.world.mazes.builtin import crossroad
from mbn.world.rollout import Observation, RolloutConfig, rollout


def _net(seed: int):
    return Genome().network(jax.random.uniform(jax.random.key(seed), (12,), minval=-8, maxval=8))


def _stacked(*nets):
    return jax.tree.map(lambda *a: jnp.stack(a), *nets)


def test_a_reference_equal_to_the_driver_has_no_mismatch_and_changes_nothing():
    net, other = _net(0), _net(1)
    maze = crossroad("LSR")
    world = compile_mazes([maze])
    poses = jnp.asarray(maze.starts[:1], jnp.float32)
    config = RolloutConfig(steps=100, record_every=1)
    start = jax.tree.map(lambda a: a[None], initial_state(net))
    drive = ctrnn_controller(substeps=20)
    plain = rollout(world, drive, start, poses, jnp.zeros(1, jnp.int32), config)
    refs = _stacked(net, other)
    state = ShadowedState(
        start,
        CTRNNState(jax.tree.map(lambda a: a[None], refs), jnp.zeros((1, 2, 3))),
        jnp.zeros((1, 2)),
    )
    shadow = rollout(world, shadowed(drive), state, poses, jnp.zeros(1, jnp.int32), config)
    # riding along does not change the drive
    np.testing.assert_array_equal(
        np.asarray(shadow.trajectory.pose), np.asarray(plain.trajectory.pose)
    )
    mismatch = np.asarray(shadow.controller_state.mismatch[0]) / config.steps
    assert mismatch[0] == 0.0  # the driver itself: no mismatch at all
    assert mismatch[1] > 0.01  # another network commands otherwise


def test_one_step_mismatch_is_the_normalised_command_difference():
    net, ref = _net(2), _net(3)
    motor = MotorMap()
    obs = Observation(
        jnp.zeros(10),
        jnp.zeros(10),
        jnp.asarray([0.7, 0.2, 0.4]),
        jnp.asarray(0),
        *(jnp.zeros(()),) * 4,
    )
    plain = ctrnn_controller(substeps=20)
    _, (v, w) = plain(initial_state(net), obs)
    _, (vr, wr) = plain(initial_state(ref), obs)
    state = ShadowedState(
        initial_state(net), CTRNNState(_stacked(ref), jnp.zeros((1, 3))), jnp.zeros(1)
    )
    out, (vs, ws) = shadowed(plain, substeps=20)(state, obs)
    assert (float(vs), float(ws)) == (float(v), float(w))
    want = abs(float(v - vr)) / motor.v_max + abs(float(w - wr)) / (2 * motor.w_max)
    assert float(out.mismatch[0]) == pytest.approx(want, rel=1e-5, abs=1e-7)
