"""The monolithic contender of the three-behaviour task: its genome's layout, and its fitness
against the followers' on the episodes both run."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.experiments.crossroads import CrossroadTask
from mbn.experiments.evolve import Genome, crossroad_fitness
from mbn.experiments.stages.monolithic import (
    MonolithicGenome,
    monolithic_fitness,
    priming_inputs,
)
from mbn.world.engine import CameraConfig

CAMERA = CameraConfig(range=0.8)


def _genes(genome: MonolithicGenome, W, sonar, tiles, bias) -> np.ndarray:
    return np.concatenate([np.ravel(W), sonar, np.ravel(tiles), bias])


def test_the_genome_lays_out_weights_sonar_diagonal_tile_weights_and_biases():
    g = MonolithicGenome(neurons=5, kinds=3)
    assert g.size == 25 + 3 + 15 + 5
    rng = np.random.default_rng(0)
    W, sonar = rng.normal(size=(5, 5)), rng.normal(size=3)
    tiles, bias = rng.normal(size=(5, 3)), rng.normal(size=5)
    net = g.network(_genes(g, W, sonar, tiles, bias))
    np.testing.assert_allclose(net.W, W, rtol=1e-6)
    we = np.asarray(net.WE)
    assert we.shape == (5, 6)
    np.testing.assert_allclose(np.diag(we[:3, :3]), sonar, rtol=1e-6)
    assert np.count_nonzero(we[:, :3]) == 3  # I_k reaches neuron k only, as in the followers
    np.testing.assert_allclose(we[:, 3:], tiles, rtol=1e-6)
    np.testing.assert_allclose(net.bias, bias, rtol=1e-6)
    # a batch of genomes gives a batch of networks
    batch = g.batch(jnp.stack([_genes(g, W, sonar, tiles, bias)] * 2))
    assert batch.W.shape == (2, 5, 5) and batch.WE.shape == (2, 5, 6)
    with pytest.raises(MbnInputError, match="at least 3 neurons"):
        MonolithicGenome(neurons=2)


def test_priming_shows_one_tile_then_nothing_with_the_sonars_silent():
    rows = priming_inputs(3, 2, see=1.5, hold=3.0)
    assert rows.shape == (45, 6)
    assert np.all(rows[:15, 4] == 1) and np.count_nonzero(rows[:15]) == 15
    assert np.count_nonzero(rows[15:]) == 0


def _follower_like(neurons: int, kinds: int):
    """A follower-shaped network inside the monolithic genome: recurrent weights among the
    first three neurons, the sonar diagonal, nothing else."""
    rng = np.random.default_rng(7)
    g = MonolithicGenome(neurons=neurons, kinds=kinds)
    W = np.zeros((neurons, neurons))
    W[:3, :3] = rng.uniform(-8, 8, (3, 3))
    sonar = rng.uniform(-8, 8, 3)
    genes = _genes(g, W, sonar, np.zeros((neurons, kinds)), np.zeros(neurons))
    follower = np.concatenate([np.ravel(W[:3, :3]), sonar])  # the RF genome's order
    return g, genes, follower


def test_a_follower_inside_the_genome_scores_as_the_follower_on_the_tile_crossroads():
    g, genes, follower = _follower_like(neurons=5, kinds=1)
    task = CrossroadTask(rule="right", tile=1, variants=2, seconds=8.0)
    mono = monolithic_fitness(g, [task], CAMERA, switches=False)
    plain = crossroad_fitness(Genome(), task)
    got = float(mono(jnp.asarray(genes[None], jnp.float32))[0])
    want = float(plain(jnp.asarray(follower[None], jnp.float32))[0])
    assert got == pytest.approx(want, rel=1e-4, abs=1e-4)


@pytest.mark.slow
def test_the_rest_episodes_score_the_crossroads_without_a_tile_by_the_first_rule():
    g, genes, follower = _follower_like(neurons=4, kinds=1)
    tiled = CrossroadTask(rule="right", tile=1, variants=1, seconds=8.0)
    bare = CrossroadTask(rule="right", variants=1, seconds=8.0)
    pop = jnp.asarray(genes[None], jnp.float32)
    got = float(monolithic_fitness(g, [tiled], CAMERA, switches=False, rest=bare)(pop)[0])
    want = sum(
        float(crossroad_fitness(Genome(), t)(jnp.asarray(follower[None], jnp.float32))[0])
        for t in (tiled, bare)
    )
    assert got == pytest.approx(want, rel=1e-4, abs=1e-4)
    with pytest.raises(MbnInputError, match="the rest task has a tile"):
        monolithic_fitness(g, [tiled], CAMERA, rest=tiled)


@pytest.mark.slow
def test_switch_episodes_start_each_crossroad_again_after_the_other_tiles():
    # without recurrent weights a network primed in open space stays at rest, so each switch
    # episode repeats its crossroad's start-mark episode: with one start per crossroad the
    # fitness with switches is the plain fitness times the number of tile kinds
    g, genes, _ = _follower_like(neurons=4, kinds=2)
    genes = genes.copy()
    genes[: 4 * 4] = 0.0  # no recurrence
    tasks = [
        CrossroadTask(rule=r, tile=k + 1, variants=1, seconds=6.0)
        for k, r in enumerate(("right", "left"))
    ]
    pop = jnp.asarray(genes[None], jnp.float32)
    once = float(monolithic_fitness(g, tasks, CAMERA, switches=False)(pop)[0])
    switched = float(monolithic_fitness(g, tasks, CAMERA, switches=True)(pop)[0])
    assert switched == pytest.approx(2 * once, rel=1e-5, abs=1e-5)
    assert once != 0.0


def test_tasks_must_match_the_tile_kinds():
    g = MonolithicGenome(neurons=3, kinds=2)
    with pytest.raises(MbnInputError, match="1 tasks for a genome of 2 tile kinds"):
        monolithic_fitness(g, [CrossroadTask(tile=1)], CAMERA)
    with pytest.raises(MbnInputError, match="task 1 has tile 1, expected 2"):
        monolithic_fitness(g, [CrossroadTask(tile=1), CrossroadTask(tile=1)], CAMERA)


def test_rf_embedded_in_the_genome_is_the_follower_shaped_network():
    import jax

    from mbn.experiments.stages.contest import neighbour_population as around
    from mbn.experiments.stages.monolithic import add_tile_kind, embed_rf

    g, genes, follower = _follower_like(neurons=6, kinds=2)
    rf = Genome().network(jnp.asarray(follower))
    np.testing.assert_allclose(embed_rf(g, rf), genes, atol=1e-6)
    pop = around(genes, jax.random.key(0), 5, 2.0, 10.0)
    np.testing.assert_array_equal(pop[0], np.clip(genes, -10, 10))  # the first member itself
    assert np.all(np.abs(pop) <= 10.0) and np.std(pop[1:] - genes) > 0.5
    grown = add_tile_kind(pop, g, jax.random.key(1), 2.0, 10.0)
    three = MonolithicGenome(neurons=6, kinds=3)
    assert grown.shape == (5, three.size)
    before, after = g.batch(jnp.asarray(pop)), three.batch(jnp.asarray(grown))
    # every weight kept; the new tile input's weights are the only new genes
    np.testing.assert_array_equal(np.asarray(after.W), np.asarray(before.W))
    np.testing.assert_array_equal(np.asarray(after.WE)[..., :5], np.asarray(before.WE))
    np.testing.assert_array_equal(np.asarray(after.bias), np.asarray(before.bias))
    assert np.all(np.asarray(after.WE)[..., 5] != 0)
    with pytest.raises(MbnInputError, match="a genome of"):
        add_tile_kind(pop[:, :-1], g, jax.random.key(1), 2.0, 10.0)
