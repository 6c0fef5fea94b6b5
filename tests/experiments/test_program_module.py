"""The program module and the MBN controller: gene layout, camera-driven programs, latching."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from mbn.ctrnn import firing_rate
from mbn.errors import MbnInputError
from mbn.experiments.evolve import Genome
from mbn.experiments.program_module import MBNState, PMGenome, mbn_controller
from mbn.multiplier import load_default
from mbn.programmable import Connection, Programmable, build_interpreter
from mbn.world.rollout import Observation


def _obs(camera: int) -> Observation:
    z = jnp.zeros(())
    return Observation(
        jnp.zeros(10), jnp.zeros(10), jnp.full(3, 0.2), jnp.asarray(camera), z, z, z, z
    )


def test_genes_map_to_weights_inputs_and_biases():
    g = PMGenome(programs=2)
    assert g.size == 4 + 4 + 2
    net = g.network(jnp.arange(10.0))
    np.testing.assert_array_equal(np.asarray(net.W), [[0, 1], [2, 3]])
    np.testing.assert_array_equal(np.asarray(net.WE), [[4, 5], [6, 7]])
    np.testing.assert_array_equal(np.asarray(net.bias), [8, 9])
    with pytest.raises(MbnInputError, match="programs"):
        PMGenome(programs=0)


def test_a_latching_program_module_keeps_the_last_tile_program():
    """Self-excitation 10 with bias -5 is bistable: the program stays after the tile is gone."""
    g = PMGenome(programs=3)
    W = np.eye(3) * 10
    WE = np.array([[10, -10], [-10, 10], [-10, 10]], float)
    pm = g.network(jnp.asarray(np.concatenate([W.ravel(), WE.ravel(), np.full(3, -5.0)])))
    conns = [Programmable(Connection("WE", 1, k), -20.0, 20.0) for k in range(3)]
    im = build_interpreter(Genome().network(np.zeros(12)), conns, load_default())
    ctrl = mbn_controller()
    state = MBNState(pm, jnp.zeros(3), im.net, jnp.zeros(im.num_neurons))
    programs = []
    for camera in [1] * 20 + [0] * 40 + [2] * 20 + [0] * 40:
        state, _ = ctrl(state, _obs(camera))
        programs.append(np.asarray(firing_rate(state.pm, state.pm_y)))
    programs = np.array(programs)
    assert programs[59, 0] > 0.98 and np.all(programs[59, 1:] < 0.02)  # one-colour, remembered
    assert programs[119, 0] < 0.02 and np.all(programs[119, 1:] > 0.98)  # two-colour, remembered
