"""The crossroad task: rule exits, the paper's fitness terms, the branch fitness, the evolution."""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.evolution.de import DEConfig
from mbn.experiments.crossroads import (
    CrossroadTask,
    branch_progress,
    episode_fitness,
    paper_terms,
    rule_arm,
)
from mbn.experiments.evolve import RF_CONNECTIONS, Genome, crossroad_fitness, generation, start
from mbn.networks.programmable import Connection
from mbn.world.rollout import EpisodeStats


def stats(**values) -> EpisodeStats:
    """Synthetic statistics of n episodes (defaults: a clean, still robot)."""
    n = len(next(iter(values.values())))
    base = {
        "stall_fraction": np.zeros(n),
        "mean_v": np.zeros(n),
        "mean_abs_w": np.zeros(n),
        "min_range": np.full(n, 5.0),
        "range_mean": np.full((n, 10), 5.0),
        "S_mean": np.zeros((n, 10)),
        "distance": np.zeros(n),
        "final_pose": np.zeros((n, 3)),
        "tile": np.zeros(n, int),
        "n_junctions": np.zeros(n, int),
    }
    for name in ("cell",):
        base[f"junction_{name}"] = np.full((n, 8, 2), -1)
    for name in ("heading", "exit", "right", "left", "open", "tile", "step", "exit_step", "stalls"):
        base[f"junction_{name}"] = np.full((n, 8), -1)
    base.update({k: np.asarray(v) for k, v in values.items()})
    return EpisodeStats(**{k: jnp.asarray(v) for k, v in base.items()})


def test_rule_arms_of_the_seven_kinds():
    right = {k: rule_arm(k, "right") for k in ("L", "S", "R", "LS", "LR", "SR", "LSR")}
    left = {k: rule_arm(k, "left") for k in ("L", "S", "R", "LS", "LR", "SR", "LSR")}
    assert right == {"L": "L", "S": "S", "R": "R", "LS": "S", "LR": "R", "SR": "R", "LSR": "R"}
    assert left == {"L": "L", "S": "S", "R": "R", "LS": "L", "LR": "L", "SR": "S", "LSR": "L"}
    with pytest.raises(MbnInputError, match="rule"):
        rule_arm("L", "up")
    with pytest.raises(MbnInputError, match="crossroad kind"):
        rule_arm("X", "right")


def test_paper_terms_are_eq_4_and_5():
    S = np.zeros((2, 10))
    S[0, [0, 1]] = 0.8  # right side near
    S[1, [8, 9]] = 0.6  # left side near
    s = stats(
        mean_v=np.array([0.25, 0.5]),
        mean_abs_w=np.array([0.0, np.pi / 4]),
        min_range=np.array([1.0, 3.0]),
        S_mean=S,
    )
    t = paper_terms(s)
    np.testing.assert_allclose(t["F_M"], [0.5 * 1.0 * 0.5, 1.0 * 0.5 * 1.0])
    np.testing.assert_allclose(t["F_R"], [1.6, -1.2])
    np.testing.assert_allclose(t["F_L"], [-1.6, 1.2])


def test_branch_fitness_rewards_the_rule_arm_and_punishes_stalling():
    task = CrossroadTask(rule="right", variants=1)
    arrays = task.arrays()
    kinds = ["L", "S", "R", "LS", "LR", "SR", "LSR"]
    lsr = kinds.index("LSR")
    centre = arrays.centre[lsr]
    ends = {  # final positions at the far end of each arm of the plus crossing
        "R": centre + np.array([0.6 + 3.6, 0.0]),
        "L": centre - np.array([0.6 + 3.6, 0.0]),
        "S": centre + np.array([0.0, 0.6 + 3.6]),
        "mid": centre + np.array([0.6 + 1.8, 0.0]),
    }
    sub = arrays.__class__(
        **{
            **arrays.__dict__,
            "target": arrays.target[[lsr] * 4],
            "centre": arrays.centre[[lsr] * 4],
        }
    )
    final = np.array([[*ends[k], 0.0] for k in ("R", "L", "S", "mid")])
    progress = np.asarray(branch_progress(stats(final_pose=final), sub))
    np.testing.assert_allclose(progress, [1.0, 0.0, 0.0, 0.5], atol=1e-9)
    stalled = stats(final_pose=final[:1], stall_fraction=np.array([0.5]))
    sub1 = sub.__class__(**{**sub.__dict__, "target": sub.target[:1], "centre": sub.centre[:1]})
    assert float(episode_fitness(stalled, sub1, task)[0]) == pytest.approx(0.5 - 0.5)


def test_task_episodes_and_validation():
    task = CrossroadTask(variants=3, seed=4)
    a = task.arrays()
    assert a.episodes == 21 and a.poses.shape == (21, 3)
    np.testing.assert_array_equal(a.poses[:7], np.stack([m.starts[0] for m in a.mazes]))
    offsets = a.poses[7:] - np.tile(a.poses[:7], (2, 1))  # starts face north: x is lateral
    assert np.all(np.abs(offsets[:, 0]) <= 0.15) and np.all(np.abs(offsets[:, 1]) <= 0.3)
    assert np.all(np.abs(offsets[:, 2]) <= np.radians(10)) and np.any(offsets != 0)
    np.testing.assert_array_equal(task.arrays().poses, a.poses)  # seeded
    with pytest.raises(MbnInputError, match="fitness"):
        CrossroadTask(fitness="distance")
    with pytest.raises(MbnInputError, match="variants"):
        CrossroadTask(variants=0)


def test_corner_approaches_add_the_seven_kinds_entered_round_a_corner():
    task = CrossroadTask(variants=3, seed=4, approaches=("south", "west", "east"))
    a = task.arrays()
    assert a.episodes == 63 and len(a.mazes) == 21
    assert [m.name for m in a.mazes[7:9]] == ["cross_L_from_west", "cross_S_from_west"]
    # the south approach keeps the paper's starts; west/east start at the far end of the south
    # corridor facing the arm, i.e. east (heading 0) and west (heading pi)
    np.testing.assert_allclose(a.poses[:7, 2], np.pi / 2)
    np.testing.assert_allclose(a.poses[7:14], np.tile([0.6, 0.6, 0.0], (7, 1)))
    np.testing.assert_allclose(a.poses[14:21], np.tile([7.8, 0.6, np.pi], (7, 1)))
    # every kind's target arm is the same whichever way the south arm was entered
    np.testing.assert_array_equal(a.target[:7], a.target[7:14])
    np.testing.assert_array_equal(a.target[:7], a.target[14:21])
    # jitter is relative to the heading: along it up to 0.3 m, across it up to 0.15 m
    base = np.tile(a.poses[:21], (2, 1))
    offsets = a.poses[21:] - base
    ahead = np.stack([np.cos(base[:, 2]), np.sin(base[:, 2])], -1)
    along = np.sum(offsets[:, :2] * ahead, -1)
    across = offsets[:, 0] * ahead[:, 1] - offsets[:, 1] * ahead[:, 0]
    assert np.all(np.abs(along) <= 0.3 + 1e-12) and np.all(np.abs(across) <= 0.15 + 1e-12)
    assert np.abs(along[7:21]).max() > 0.15  # the west/east starts move along x
    # the south approach alone gives exactly the default task
    np.testing.assert_array_equal(
        CrossroadTask(variants=3, seed=4, approaches=("south",)).arrays().poses,
        CrossroadTask(variants=3, seed=4).arrays().poses,
    )
    with pytest.raises(MbnInputError, match="approaches"):
        CrossroadTask(approaches=("north",))
    with pytest.raises(MbnInputError, match="approaches"):
        CrossroadTask(approaches=())
    with pytest.raises(MbnInputError, match="twice"):
        CrossroadTask(approaches=("west", "west"))


def test_genome_maps_genes_to_connections():
    g = Genome()
    assert g.size == 12 and g.connections == RF_CONNECTIONS
    genes = np.arange(12.0)
    net = g.network(genes)
    np.testing.assert_array_equal(np.asarray(net.W), np.arange(9.0).reshape(3, 3))
    np.testing.assert_array_equal(np.asarray(net.WE), np.diag([9.0, 10.0, 11.0]))
    three = (Connection("W", 1, 2), Connection("WE", 1, 0), Connection("WE", 1, 1))
    lf = Genome.around(net, three)
    np.testing.assert_array_equal(lf.genes_of(net), [5.0, 0.0, 10.0])
    W, WE = lf.weights(jnp.asarray([-1.0, 2.0, 3.0]))
    assert float(W[1, 2]) == -1.0 and float(WE[1, 0]) == 2.0 and float(WE[1, 1]) == 3.0
    assert float(W[0, 0]) == 0.0 and float(WE[2, 2]) == 11.0


def test_evolution_is_deterministic_and_never_gets_worse():
    task = CrossroadTask(variants=1, seconds=4.0)
    genome = Genome()
    fitness = crossroad_fitness(genome, task)
    config = DEConfig(num_dims=12, popsize=6, maximize=True, lower=-100.0, upper=100.0)
    key = jax.random.key(3)

    def run():
        state = start(key, config, fitness)
        best = [float(state.best_fitness)]
        for g in range(1, 4):
            state = generation(key, g, state, config, fitness)
            best.append(float(state.best_fitness))
        return best, np.asarray(state.population)

    a, pa = run()
    b, pb = run()
    assert a == b and np.array_equal(pa, pb)
    assert all(x <= y for x, y in itertools.pairwise(a))
    with pytest.raises(MbnInputError, match="generation"):
        generation(key, 0, start(key, config, fitness), config, fitness)


def test_interpreter_programs_equal_the_builder():
    """The batched, traceable interpreter of a network equals build_interpreter's."""
    from mbn.experiments.evolve import interpreter_programs
    from mbn.networks.multiplier import load_default
    from mbn.networks.programmable import Programmable, build_interpreter

    rng = np.random.default_rng(0)
    conns = (Connection("W", 1, 2), Connection("WE", 1, 0), Connection("WE", 1, 1))
    bounds = [Programmable(c, -100.0, 100.0) for c in conns]
    template = build_interpreter(Genome().network(np.zeros(12)), bounds, load_default())
    genes = rng.uniform(-90, 90, (4, 12))
    W, WE = Genome().weights(jnp.asarray(genes))
    net, program = interpreter_programs(template, W, WE)
    for k in range(4):
        ref = build_interpreter(Genome().network(genes[k]), bounds, load_default())
        np.testing.assert_allclose(np.asarray(net.W[k]), np.asarray(ref.net.W), atol=1e-12)
        np.testing.assert_allclose(np.asarray(net.WE[k]), np.asarray(ref.net.WE), atol=1e-12)
        np.testing.assert_allclose(np.asarray(net.tau[k]), np.asarray(ref.net.tau), atol=1e-12)
        np.testing.assert_allclose(
            np.asarray(program[k]),
            np.asarray(ref.program_of(Genome().network(genes[k]))),
            atol=1e-12,
        )


def test_connection_search_fitness_equals_the_genome_fitness_for_every_triple():
    """One compiled function for every choice of connections gives exactly what
    crossroad_fitness of Genome.around gives."""
    from mbn.experiments.evolve import connection_search_fitness
    from mbn.networks.programmable import Connection
    from mbn.paper import published_rf

    base = published_rf()
    task = CrossroadTask(rule="left", variants=1, seconds=4.0)
    arrays = task.arrays()
    search = connection_search_fitness(base, task, arrays)
    pop = jax.random.uniform(jax.random.key(1), (4, 3), minval=-20.0, maxval=20.0)
    triples = [
        (Connection("W", 1, 0), Connection("WE", 1, 1), Connection("WE", 1, 2)),
        (Connection("W", 0, 2), Connection("W", 2, 2), Connection("WE", 0, 0)),
    ]
    for trip in triples:
        expected = crossroad_fitness(Genome.around(base, trip), task, arrays)(pop)
        np.testing.assert_array_equal(np.asarray(search(pop, trip)), np.asarray(expected))
    with pytest.raises(MbnInputError, match="2 connections for genomes of 3 genes"):
        search(pop, triples[0][:2])


def test_a_group_of_connection_choices_evaluated_as_one_batch_gives_each_choices_fitness():
    """Genome i of the batch re-evolves choices[owner[i]]: exactly the fitness of its choice's
    own population of the same size (the networks are the same, bit for bit)."""
    from mbn.experiments.evolve import connection_group_fitness, connection_search_fitness
    from mbn.networks.programmable import Connection
    from mbn.paper import published_rf

    base = published_rf()
    task = CrossroadTask(rule="left", variants=1, seconds=4.0)
    arrays = task.arrays()
    choices = [
        (Connection("W", 1, 0), Connection("WE", 1, 1), Connection("WE", 1, 2)),
        (Connection("W", 0, 2), Connection("W", 2, 2), Connection("WE", 0, 0)),
    ]
    group = connection_group_fitness(base, task, choices, arrays)
    search = connection_search_fitness(base, task, arrays)
    pop = jax.random.uniform(jax.random.key(2), (4, 3), minval=-20.0, maxval=20.0)
    # the same genomes under each choice, and a batch of the same size for each alone
    together = np.asarray(group(pop, np.array([0, 1, 0, 1])))
    for k in range(2):
        alone = np.asarray(search(pop, choices[k]))
        np.testing.assert_array_equal(together[k::2], alone[k::2])
    with pytest.raises(MbnInputError, match="one size expected"):
        connection_group_fitness(base, task, [choices[0], choices[1][:2]], arrays)


def test_a_task_under_noise_needs_a_key_and_gives_a_deterministic_fitness():
    """Episodes under noise (the run's ``[noise]``): refused without a key; with one, the same
    fitness at every call (common random numbers for DE), another key gives another, and noise
    at level 0 changes nothing (to the last bit)."""
    from mbn.paper import published_rf
    from mbn.world.sensors import NoiseConfig

    noise = NoiseConfig(sonar_std=0.05, sonar_dropout=0.05, wheel_std=0.1)
    with pytest.raises(MbnInputError, match="noise_key"):
        CrossroadTask(variants=1, seconds=6.0, noise=noise)
    genome = Genome()
    rf = published_rf()
    population = jnp.stack(
        [genome.genes_of(rf)] * 2
        + [jax.random.uniform(jax.random.key(1), (12,), minval=-5, maxval=5)]
    ).astype(jnp.float32)

    def values(**kw):
        task = CrossroadTask(variants=2, seconds=6.0, **kw)
        return np.asarray(crossroad_fitness(genome, task)(population))

    clean = values()
    noisy = values(noise=noise, noise_key=jax.random.key(5))
    np.testing.assert_array_equal(noisy, values(noise=noise, noise_key=jax.random.key(5)))
    assert not np.array_equal(noisy, values(noise=noise, noise_key=jax.random.key(6)))
    assert not np.allclose(noisy, clean, rtol=0, atol=1e-4)
    np.testing.assert_array_equal(values(noise=NoiseConfig(), noise_key=jax.random.key(5)), clean)
