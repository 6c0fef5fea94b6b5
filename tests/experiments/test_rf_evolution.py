"""End to end (slow): DE evolves a right-follower on the crossroads that passes the paper's test."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.control.ctrnn import NETWORK_SUBSTEPS, ctrnn_controller, initial_state
from mbn.evolution.de import DEConfig
from mbn.experiments.crossroads import CrossroadTask
from mbn.experiments.evolve import Genome, crossroad_fitness, generation, start
from mbn.experiments.trials import TrialSpec, run_trials, summary
from mbn.world.mazes.builtin import builtin_maze


@pytest.mark.slow
def test_evolved_right_follower_passes_the_paper_protocol():
    genome = Genome()
    task = CrossroadTask(rule="right", seed=1)
    fitness = crossroad_fitness(genome, task)
    config = DEConfig(num_dims=genome.size, maximize=True, lower=-100.0, upper=100.0)
    key = jax.random.key(1)
    state = start(key, config, fitness)
    for g in range(1, 601):
        state = generation(key, g, state, config, fitness)
    net = genome.network(np.asarray(state.population[int(jnp.argmax(state.fitness))]))
    controller = ctrnn_controller(dt=0.1, substeps=NETWORK_SUBSTEPS)

    def init(n):
        return initial_state(jax.tree.map(lambda a: jnp.broadcast_to(a, (n, *a.shape)), net))

    paper = summary(run_trials(builtin_maze("fig4"), TrialSpec(), controller, init)[0])
    jitter = TrialSpec(repeats=20, seed=1)
    jittered = summary(run_trials(builtin_maze("fig4"), jitter, controller, init)[0])
    heldout = summary(run_trials(builtin_maze("heldout"), jitter, controller, init)[0])
    assert paper["successes"] == 10
    assert jittered["success_rate"] >= 0.95
    assert heldout["success_rate"] >= 0.95
