"""Fitness averaged over perturbed copies of each genome (``mbn.experiments.evolve``)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.experiments.evolve import perturbations, robust_fitness


def _sphere(population: jax.Array) -> jax.Array:
    return -jnp.sum(population**2, axis=-1)


def test_perturbations_are_fixed_by_the_key_and_scaled_by_sigma() -> None:
    key = jax.random.key(3)
    a = perturbations(key, 4000, 5, 0.3)
    b = perturbations(key, 4000, 5, 0.3)
    assert a.shape == (4000, 5)
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    # 20 000 normal draws: the sample deviation is within 2 % of sigma
    assert abs(float(jnp.std(a)) - 0.3) < 0.006
    assert abs(float(jnp.mean(a))) < 0.01
    other = perturbations(jax.random.key(4), 4000, 5, 0.3)
    assert not np.allclose(np.asarray(a), np.asarray(other))


def test_no_copies_leaves_the_fitness_unchanged() -> None:
    noise = perturbations(jax.random.key(0), 0, 3, 0.3)
    assert robust_fitness(_sphere, noise) is _sphere


def test_robust_fitness_is_the_mean_over_the_genome_and_its_copies() -> None:
    pop = jnp.asarray([[1.0, 2.0, -1.0], [0.0, 0.5, 3.0]])
    noise = jnp.asarray([[0.1, -0.2, 0.0], [0.3, 0.3, -0.3]])
    got = np.asarray(robust_fitness(_sphere, noise)(pop))
    want = [
        np.mean([-np.sum(np.asarray(g)[None] ** 2) for g in (p, p + noise[0], p + noise[1])])
        for p in pop
    ]
    np.testing.assert_allclose(got, want, rtol=1e-6)


def test_robust_fitness_evaluates_every_copy_in_one_batch() -> None:
    calls: list[tuple[int, ...]] = []

    def counting(population: jax.Array) -> jax.Array:
        calls.append(tuple(population.shape))
        return _sphere(population)

    robust_fitness(counting, perturbations(jax.random.key(1), 3, 4, 0.3))(jnp.ones((18, 4)))
    assert calls == [(4 * 18, 4)]


def test_robust_fitness_prefers_the_wide_optimum() -> None:
    """Two peaks of equal height: the narrow one wins without noise, the wide one with it."""

    def two_peaks(population: jax.Array) -> jax.Array:
        x = population[:, 0]
        narrow = 1.0 * jnp.exp(-(((x - 1.0) / 0.05) ** 2))
        wide = 0.95 * jnp.exp(-(((x + 1.0) / 1.0) ** 2))
        return narrow + wide

    candidates = jnp.asarray([[1.0], [-1.0]])
    plain = np.asarray(two_peaks(candidates))
    robust = np.asarray(
        robust_fitness(two_peaks, perturbations(jax.random.key(0), 16, 1, 0.3))(candidates)
    )
    assert plain[0] > plain[1]
    assert robust[1] > robust[0] + 0.3


def test_bad_perturbation_settings_are_refused() -> None:
    with pytest.raises(MbnInputError, match="copies"):
        perturbations(jax.random.key(0), -1, 3, 0.3)
    with pytest.raises(MbnInputError, match="sigma"):
        perturbations(jax.random.key(0), 2, 3, -0.1)
    with pytest.raises(MbnInputError, match="3 genes for genomes of 2"):
        robust_fitness(_sphere, jnp.zeros((2, 3)))(jnp.ones((5, 2)))


def test_a_population_evaluated_in_parts_gets_the_same_values_with_any_number_of_threads():
    """split_fitness (the run's --threads) changes how fast a population is evaluated, not
    what: it always evaluates the same parts (FITNESS_PARTS), so the values are the same bit for
    bit with 1, 2, 3 or 9 threads, and equal those of the parts evaluated by hand. (Evaluated
    whole, the same population may differ in the last digits: XLA's sums depend on the shape.)"""
    from mbn.experiments.crossroads import CrossroadTask
    from mbn.experiments.evolve import (
        FITNESS_PARTS,
        Genome,
        crossroad_fitness,
        perturbations,
        robust_fitness,
        split_fitness,
    )

    genome = Genome()
    task = CrossroadTask(rule="right", variants=2, seconds=6.0, seed=1)
    fitness = robust_fitness(
        crossroad_fitness(genome, task), perturbations(jax.random.key(0), 2, genome.size, 0.3)
    )
    population = jnp.asarray(
        np.random.default_rng(0).uniform(-20, 20, (7, genome.size)), jnp.float32
    )
    assert FITNESS_PARTS == 2
    by_hand = np.concatenate(
        [np.asarray(fitness(population[:4])), np.asarray(fitness(population[4:]))]
    )
    assert np.unique(by_hand).size > 3  # the genomes differ, so a shuffled result would show
    for workers in (1, 2, 3, 9):
        parted = np.asarray(split_fitness(fitness, workers)(population))
        np.testing.assert_array_equal(parted, by_hand)
    one = np.asarray(split_fitness(fitness, 4, parts=1)(population))
    np.testing.assert_array_equal(one, np.asarray(fitness(population)))


@pytest.mark.slow  # one program for many finalists is speed; a genome against its network:
# test_crossroads.py, test_connection_search_fitness_equals_the_genome_fitness_for_every_triple
def test_finalists_around_different_networks_share_one_compiled_fitness() -> None:
    """The crossroads' fitness takes the base network and the task's arrays as arguments: the
    genomes of two LF finalists around two RFs (other weights, other connections) run on one
    compiled program, and give what each genome's own network gives. So do tasks of other
    seeds (other jittered starts): the starts are arguments too."""
    from mbn.experiments.crossroads import CrossroadTask
    from mbn.experiments.evolve import (
        Genome,
        _owned_fitness,
        crossroad_fitness,
        evaluate_networks,
        tile_fitness,
    )
    from mbn.networks.ctrnn import make_ctrnn
    from mbn.networks.programmable import Connection

    task = CrossroadTask(rule="left", variants=1, seconds=1.0)
    rng = np.random.default_rng(1)
    nets = [make_ctrnn(rng.normal(size=(3, 3)), np.diag(rng.normal(size=3)), 0.5) for _ in (0, 1)]
    choices = [
        (Connection("W", 1, 0), Connection("W", 1, 1), Connection("WE", 1, 1)),
        (Connection("W", 1, 2), Connection("WE", 1, 0), Connection("WE", 1, 2)),
    ]
    population = jnp.asarray(rng.normal(size=(4, 3)))
    values = []
    before = None
    for net, conns in zip(nets, choices, strict=True):
        genome = Genome.around(net, conns)
        values.append(np.asarray(crossroad_fitness(genome, task)(population)))
        if before is None:
            before = _owned_fitness._cache_size()
    other_seed = CrossroadTask(rule="left", variants=1, seconds=1.0, seed=7)
    crossroad_fitness(Genome.around(nets[0], choices[0]), other_seed)(population)
    assert _owned_fitness._cache_size() == before
    # each value is the fitness of the genome's own network
    genome = Genome.around(nets[1], choices[1])
    arrays = task.arrays()
    W, WE = genome.weights(population)
    stats = evaluate_networks(W, WE, genome.tau, arrays, task)
    own = np.asarray(tile_fitness(arrays)(stats, task)).reshape(4, arrays.episodes).sum(-1)
    np.testing.assert_allclose(values[1], own, rtol=1e-9, atol=1e-9)


def test_rows_are_cut_and_joined_on_the_host_as_slices_and_concatenation_would() -> None:
    from mbn.experiments.evolve import join_rows, split_rows
    from mbn.host import put

    x = jnp.arange(30.0).reshape(10, 3)
    parts = split_rows(x, (0, 4, 10))
    assert [p.shape for p in parts] == [(4, 3), (6, 3)]
    np.testing.assert_array_equal(np.asarray(parts[1]), np.asarray(x[4:]))
    np.testing.assert_array_equal(np.asarray(join_rows(parts)), np.asarray(x))
    assert put(np.zeros(3, np.float32)).dtype == jnp.float32
    assert put([1, 2], np.int32).dtype == jnp.int32
