"""Training episodes drawn from a maze family (``mbn.experiments.maze_task``): seeded draws from
a pool of train-split mazes, a fitness that judges junction passes as the tests do, and one
compiled program for every draw."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.experiments.evolve import Genome, _owned_fitness, crossroad_fitness, evaluate_networks
from mbn.experiments.maze_task import MazeTask, junction_progress, maze_episode_fitness
from mbn.experiments.trials import TrialSpec, judge
from mbn.networks.ctrnn import make_ctrnn
from mbn.networks.programmable import Connection
from mbn.world.mazes import families as fm
from mbn.world.stats import EpisodeStats

#: A small pool and short episodes: the same code paths as the defaults, quickly.
SMALL = {"pool": 12, "mazes": 4, "starts": 3, "seconds": 25.0}


def _random_net():
    rng = np.random.default_rng(3)
    return make_ctrnn(rng.normal(0, 4, (3, 3)), rng.normal(0, 6, (3, 3)), 0.5)


def test_draws_are_seeded_from_a_train_pool_and_differ_from_draw_to_draw():
    task = MazeTask(**SMALL)
    seeds = task.pool_seeds()
    assert len(seeds) == 12 and all(fm.split_of(s) == "train" for s in seeds)
    a, again, other = task.arrays(), MazeTask(**SMALL).arrays(), task.redrawn(1).arrays()
    assert a.episodes == 12 and a.poses.shape == (12, 3)
    np.testing.assert_array_equal(a.poses, again.poses)
    np.testing.assert_array_equal(a.maze_index, again.maze_index)
    assert not np.array_equal(a.poses, other.poses)
    assert [m.name for m in a.mazes] == [f"grid:{s}" for s in seeds]
    # every start lies within a cell of one of its maze's start marks (jittered, not moved away)
    for pose, m in zip(a.poses, a.maze_index, strict=True):
        marks = a.mazes[m].starts
        assert np.min(np.hypot(*(marks[:, :2] - pose[:2]).T)) <= 0.35
    assert MazeTask(**{**SMALL, "seed": 1}).pool_seeds() != seeds


def _stats(rng: np.random.Generator, b: int, k: int = 8) -> EpisodeStats:
    """Episodes with random junction passes (exits, open exits holding the exit taken, tiles,
    exit steps and stalls), the other statistics zero."""
    n = rng.integers(0, 6, b)
    exits = rng.integers(0, 4, (b, k))
    opened = rng.integers(0, 16, (b, k)) | (1 << exits)
    tile = rng.integers(0, 3, (b, k))
    exit_step = np.cumsum(rng.integers(5, 60, (b, k)), axis=1)
    stalls = np.minimum(
        np.cumsum(rng.integers(0, 2, (b, k)) * rng.integers(0, 3, (b, k)), 1), exit_step
    )
    passed = np.arange(k)[None] < np.minimum(n, k)[:, None]
    hole = lambda a: np.where(passed, a, -1).astype(np.int32)  # noqa: E731
    zeros = np.zeros(b)
    return EpisodeStats(
        stall_fraction=jnp.asarray(rng.uniform(0, 0.05, b)),
        mean_v=jnp.asarray(zeros),
        mean_abs_w=jnp.asarray(zeros),
        min_range=jnp.asarray(zeros),
        range_mean=jnp.zeros((b, 10)),
        S_mean=jnp.zeros((b, 10)),
        distance=jnp.asarray(zeros),
        final_pose=jnp.zeros((b, 3)),
        tile=jnp.zeros(b, jnp.int32),
        n_junctions=jnp.asarray(n, jnp.int32),
        junction_cell=jnp.zeros((b, k, 2), jnp.int32),
        junction_heading=jnp.asarray(hole(exits * 0)),
        junction_exit=jnp.asarray(hole(exits)),
        junction_right=jnp.asarray(hole(exits)),
        junction_left=jnp.asarray(hole(exits)),
        junction_open=jnp.asarray(hole(opened)),
        junction_tile=jnp.asarray(hole(tile)),
        junction_step=jnp.asarray(hole(exit_step - 3)),
        junction_exit_step=jnp.asarray(hole(exit_step)),
        junction_stalls=jnp.asarray(hole(stalls)),
    )


@pytest.mark.parametrize("rule", ["right", "left", "straight-right", "tiles"])
def test_the_fitness_judges_junction_passes_as_the_tests_do(rule):
    """On 4000 episodes of random junction passes: full progress without stalling exactly when
    the tests' judge calls an episode a success, the stall fraction the judge's, and the
    progress the passes right before the first wrong one (at most the judge's right passes)."""
    stats = _stats(np.random.default_rng(7), 4000)
    family = "tiles2" if rule == "tiles" else "grid"
    task = MazeTask(**SMALL, rule=rule, family=family)
    spec = TrialSpec(behavior=rule, junctions=3, initial="right")
    progress, stall = (np.asarray(x) for x in junction_progress(stats, task))
    verdict = judge(jax.tree.map(np.asarray, stats), spec)
    np.testing.assert_array_equal((progress == 1) & (stall <= 0.02), verdict["success"])
    assert 0.01 < verdict["success"].mean() < 0.99  # both kinds of episode are compared
    np.testing.assert_allclose(stall, verdict["stall"], rtol=1e-6)
    assert np.all(progress * 3 <= verdict["correct"])
    full = progress * 3 == verdict["correct"]
    assert 0 < full.mean() < 1  # a right pass after a wrong one earns no progress
    fitness = np.asarray(maze_episode_fitness(stats, task))
    np.testing.assert_allclose(fitness, progress * (1 - stall) - stall, rtol=1e-6)
    heavy = dataclasses.replace(task, stall_weight=10.0)
    np.testing.assert_allclose(
        np.asarray(maze_episode_fitness(stats, heavy)),
        progress * (1 - stall) - 10 * stall,
        rtol=1e-6,
        atol=1e-7,
    )


# slow: a second path; CI checks the fitness judges junction passes as the tests do (above)
@pytest.mark.slow
def test_the_compiled_fitness_is_the_episodes_sum_and_every_draw_shares_its_program():
    net = _random_net()
    conns = (Connection("W", 1, 2), Connection("WE", 1, 0), Connection("WE", 1, 1))
    genome = Genome.around(net, conns)
    task = MazeTask(**SMALL)
    fitness = crossroad_fitness(genome, task)
    genes = genome.genes_of(net)[None]
    value = float(fitness(jnp.asarray(genes))[0])
    arrays = task.arrays()
    stats = evaluate_networks(
        jnp.asarray(net.W)[None], jnp.asarray(net.WE)[None], 0.5, arrays, task
    )
    np.testing.assert_allclose(value, float(maze_episode_fitness(stats, task).sum()), rtol=1e-6)
    compiled = _owned_fitness._cache_size()
    redrawn = crossroad_fitness(genome, task.redrawn(1))
    other = float(redrawn(jnp.asarray(genes))[0])
    assert _owned_fitness._cache_size() == compiled  # the same program
    assert other != value


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"mazes": 20}, r"mazes \(20\) must be at most pool \(12\)"),
        ({"starts": 11}, r"starts \(11\) must be at most the family's start marks \(10\)"),
        ({"rule": "tiles"}, "rule 'tiles' needs a family with tiles"),
        ({"family": "mazes"}, "unknown maze family 'mazes'"),
        ({"rule": "up"}, "unknown rule 'up'"),
        ({"draw": -1}, "draw must be an integer >= 0"),
    ],
)
def test_settings_that_cannot_make_episodes_are_one_line(changes, message):
    with pytest.raises(MbnInputError, match=message):
        MazeTask(**{**SMALL, **changes})


def test_the_episodes_settings_choose_the_followers_training_task():
    """``[episodes] kind``: the crossroads as before, or a redrawn maze task seeded by the run's
    crossroad seed (the draw of generation g: g // redraw)."""
    from types import SimpleNamespace

    from mbn.experiments.crossroads import CrossroadTask
    from mbn.experiments.evolve import Redrawn
    from mbn.experiments.stages.common import training_fitness, training_task
    from mbn.experiments.stages.settings import (
        EpisodeSettings,
        FollowerSettings,
        ValidationSettings,
    )
    from mbn.world.sensors import NoiseConfig

    def ctx(**episodes):
        sections = {
            "episodes": EpisodeSettings(**episodes),
            "followers": FollowerSettings(),
            "validation": ValidationSettings(),
            "noise": NoiseConfig(),
        }
        return SimpleNamespace(
            section=lambda cls: sections[cls.section],
            seeds={"crossroad_jitter": 17},
            key=jax.random.key(0),
        )

    paper = training_task(ctx(kind="crossroads"), "right", 4)
    assert isinstance(paper, CrossroadTask) and paper.variants == 4 and paper.seed == 17
    assert training_fitness(ctx(kind="crossroads"), "right", 4, lambda t: t) == paper
    # the default: maze episodes (docs/reproduce.md, "Which protocol")
    assert isinstance(training_task(ctx(pool=8), "right", 4), MazeTask)
    maze = training_task(ctx(kind="maze", family="grid", pool=12, mazes=4, starts=3), "left", 4)
    assert isinstance(maze, MazeTask)
    assert (maze.rule, maze.pool, maze.mazes, maze.starts, maze.seed) == ("left", 12, 4, 3, 17)
    # the LF search's fewer starts of each maze: only the starts change
    fewer = training_task(ctx(kind="maze", pool=12, mazes=4, starts=3), "left", 2, starts=1)
    assert isinstance(fewer, MazeTask)
    assert dataclasses.replace(fewer, starts=3) == maze
    redrawn = training_fitness(ctx(kind="maze", pool=12, mazes=4, redraw=5), "left", 4, lambda t: t)
    assert isinstance(redrawn, Redrawn)
    assert [redrawn.at(g).draw for g in (0, 4, 5, 12)] == [0, 0, 1, 2]


@pytest.mark.slow  # a quick reproduction of its own (about 2 min on 2 cores)
def test_a_quick_reproduction_evolves_its_followers_on_maze_episodes(tmp_path):
    import json
    import subprocess
    import sys

    settings = tmp_path / "maze.toml"
    settings.write_text('[episodes]\nkind = "maze"\npool = 32\nredraw = 5\n')
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "mbn", "reproduce", "--quick", "--seed", "3", "--quiet"]
    proc = subprocess.run(
        [*cmd, "--config", str(settings), "--out", str(out)], capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    results = json.loads((out / "results.json").read_text())
    assert results["config"]["episodes"]["kind"] == "maze"
    assert results["config"]["episodes"]["redraw"] == 5
    for stage in ("rf", "lf_search", "lf", "tests"):
        assert stage in results["stages"]
