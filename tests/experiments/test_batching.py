"""Population evaluations merged across threads (``mbn.experiments.batching``, the engine of
``mbn sweep --batched``): each population gets, bit for bit, the values it gets alone."""

from __future__ import annotations

import contextlib
import itertools
import threading
import time

import jax
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.experiments.batching import Batcher, current
from mbn.experiments.crossroads import CrossroadTask
from mbn.experiments.evolve import (
    Genome,
    OwnedFitness,
    connection_group_fitness,
    crossroad_fitness,
    perturbations,
    robust_fitness,
)
from mbn.networks.ctrnn import make_ctrnn
from mbn.networks.programmable import Connection

TRIPLES = [
    (Connection("W", 1, 0), Connection("W", 1, 1), Connection("WE", 1, 1)),
    (Connection("W", 1, 2), Connection("WE", 1, 0), Connection("WE", 1, 2)),
]


def _seed_fitness(seed: int) -> OwnedFitness:
    """What one seed's LF search evaluates: two triples of its own RF, its own jittered
    starts (the task's seed) and its own perturbations."""
    rng = np.random.default_rng(seed)
    rf = make_ctrnn(rng.normal(size=(3, 3)), np.diag(rng.normal(size=3)), 0.5)
    task = CrossroadTask(rule="left", variants=2, seconds=2.0, seed=seed)
    group = connection_group_fitness(rf, task, TRIPLES)
    return robust_fitness(group, perturbations(jax.random.key(seed), 2, 3, 0.3))


def _population(seed: int, n: int = 6) -> np.ndarray:
    return np.random.default_rng(100 + seed).uniform(-10, 10, (n, 3)).astype(np.float32)


OWNER = np.repeat([0, 1], 3)


def test_fitnesses_of_different_seeds_share_a_signature_and_merge_row_by_row():
    a, b = _seed_fitness(1), _seed_fitness(2)
    assert a.signature == b.signature  # the same program: only the owners' rows differ
    assert not np.array_equal(a.owned[6], b.owned[6])  # their starts differ
    pa, pb = _population(1), _population(2)
    alone = [np.asarray(a(pa, OWNER)), np.asarray(b(pb, OWNER))]
    population, owner, owned = OwnedFitness.merged([(a, pa, OWNER), (b, pb, OWNER)])
    assert owner.tolist() == [0, 0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 3]
    together = np.asarray(a.evaluate(population, owner, owned))
    assert np.unique(together).size > 6  # the genomes differ, so a mix-up would show
    np.testing.assert_array_equal(together[:6], alone[0])
    np.testing.assert_array_equal(together[6:], alone[1])


def test_a_fitness_of_another_task_is_not_merged():
    genome = Genome()
    rf = crossroad_fitness(genome, CrossroadTask(rule="right", variants=1, seconds=2.0))
    assert rf.signature != _seed_fitness(1).signature
    requests = [
        (rf, np.zeros((2, 12), np.float32), np.zeros(2, int)),
        (_seed_fitness(1), _population(1), OWNER),
    ]
    with pytest.raises(MbnInputError, match="cannot be merged"):
        OwnedFitness.merged(requests)


@pytest.mark.parametrize("workers", [1, 2])
def test_seeds_in_threads_get_their_own_values_in_one_call(workers):
    """Three seeds' threads evaluate at once through one batcher: one merged call (padded to
    a power of two of genomes and owners) gives each the values of its population alone,
    whichever parts the batch is cut into. (The patience is long and the threads evolve before
    any evaluates, so that all three are in the one call.)"""
    started = threading.Barrier(3)
    seeds = (1, 2, 3)
    fitness = {s: _seed_fitness(s) for s in seeds}
    alone = {s: np.asarray(fitness[s](_population(s), OWNER)) for s in seeds}
    batcher = Batcher(workers=workers, patience=30.0)  # all three must come
    got: dict[int, np.ndarray] = {}
    errors: list[BaseException] = []

    def seed_thread(s: int, membership) -> None:
        try:
            with membership, batcher.evolving():
                started.wait(timeout=60)
                assert current() is batcher
                got[s] = batcher.evaluate(fitness[s], _population(s), OWNER)
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=seed_thread, args=(s, batcher.enrol())) for s in seeds]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=300)
    assert not errors, errors
    assert batcher.calls == 1 and batcher.populations == 3
    for s in seeds:
        np.testing.assert_array_equal(got[s], alone[s])
    assert current() is None  # the test's own thread never was a member


def test_a_member_doing_other_work_holds_up_nobody_and_an_evolving_one_its_patience():
    """The batcher waits for the members that are evolving only: a member busy with other work
    does not hold up an evaluation; one that evolves but does not evaluate holds it up for
    ``patience`` seconds at most."""
    f = _seed_fitness(1)
    for evolving, least in ((False, 0.0), (True, 0.3)):
        batcher = Batcher(patience=0.3)
        release, entered = threading.Event(), threading.Event()
        got = {}

        def busy(batcher=batcher, release=release, entered=entered, evolving=evolving) -> None:
            with batcher.member(), batcher.evolving() if evolving else contextlib.nullcontext():
                entered.set()
                release.wait(timeout=300)  # never evaluates while the other does

        def evaluating(batcher=batcher, got=got) -> None:
            with batcher.member(), batcher.evolving():
                t0 = time.monotonic()
                got["values"] = batcher.evaluate(f, _population(1), OWNER)
                got["waited"] = time.monotonic() - t0

        b = threading.Thread(target=busy)
        b.start()
        entered.wait(timeout=60)
        e = threading.Thread(target=evaluating)
        e.start()
        e.join(timeout=300)
        release.set()
        b.join(timeout=10)
        np.testing.assert_array_equal(got["values"], np.asarray(f(_population(1), OWNER)))
        assert batcher.calls == 1 and batcher.populations == 1
        assert got["waited"] >= least, evolving


@pytest.mark.parametrize(
    "sizes", [(9, 9), pytest.param((7, 11), marks=pytest.mark.slow), (1,) * 18]
)
def test_a_genomes_value_is_the_same_in_any_batch_bit_for_bit(sizes):
    """What batching rests on: each row is computed alike whatever the batch around it (the
    robust RF fitness of 18 genomes, whole and cut into parts)."""
    genome = Genome()
    task = CrossroadTask(rule="right", variants=1, seconds=2.0, seed=1)
    f = robust_fitness(
        crossroad_fitness(genome, task), perturbations(jax.random.key(0), 2, genome.size, 0.3)
    )
    population = np.random.default_rng(0).uniform(-20, 20, (18, genome.size)).astype(np.float32)
    whole = np.asarray(f(population))
    bounds = np.cumsum((0, *sizes))
    parts = np.concatenate([np.asarray(f(population[a:b])) for a, b in itertools.pairwise(bounds)])
    assert np.unique(whole).size > 9
    np.testing.assert_array_equal(parts, whole)
