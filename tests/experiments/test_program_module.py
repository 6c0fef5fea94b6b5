"""The program module and the MBN controller: gene layout, camera-driven programs, latching."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.experiments.evolve import Genome
from mbn.experiments.program_module import MBNState, PMGenome, mbn_controller
from mbn.networks.ctrnn import firing_rate
from mbn.networks.multiplier import load_default
from mbn.networks.programmable import Connection, Programmable, build_interpreter
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
    ctrl = jax.jit(mbn_controller())  # one compiled step (eager, 120 steps took 17 s)
    state = MBNState(pm, jnp.zeros(3), im.net, jnp.zeros(im.num_neurons))
    programs = []
    for camera in [1] * 20 + [0] * 40 + [2] * 20 + [0] * 40:
        state, _ = ctrl(state, _obs(camera))
        programs.append(np.asarray(firing_rate(state.pm, state.pm_y)))
    programs = np.array(programs)
    assert programs[59, 0] > 0.98 and np.all(programs[59, 1:] < 0.02)  # one-colour, remembered
    assert programs[119, 0] < 0.02 and np.all(programs[119, 1:] > 0.98)  # two-colour, remembered


def _switch_latch() -> np.ndarray:
    """A hand-made PM that starts as the right-follower program (1, 0, 0): neurons 2 and 3 hold
    themselves on (self-excitation 10, bias -5) once a two-colour tile is seen, neuron 1 is their
    inverse; a one-colour tile resets them."""
    W = np.array([[0.0, -10.0, -10.0], [0.0, 10.0, 0.0], [0.0, 0.0, 10.0]])
    WE = np.array([[10.0, -10.0], [-10.0, 10.0], [-10.0, 10.0]])
    return np.concatenate([W.ravel(), WE.ravel(), [5.0, -5.0, -5.0]])


def test_memory_reward_episodes_and_maximum():
    from mbn.experiments.program_module import MemoryReward, memory_reward_maximum

    reward = MemoryReward()
    eps = reward.episodes()
    # 4 crossroads where the rules part x (plain, switch, memory) x 2 rules, plus 3 rest
    assert len(eps) == 4 * 6 + 3
    assert {e[3] for e in eps} == {0, 1, 2}
    assert {e[4] for e in eps} == {"south"}
    for _kind, tile, seq, label, _approach in eps:
        if label == 2:
            assert tile is None and seq == "rest"
        elif seq == "rest":
            assert tile == label + 1  # plain: the rule's own tile
        elif seq.startswith("after_"):
            assert tile == label + 1 and seq == ("after_two" if label == 0 else "after_one")
        else:
            assert tile is None and seq == ("memory_one" if label == 0 else "memory_two")
    # each rule has 12 episodes per start, rest 3: (12 * 1.1 * v + z) ** 2 with z = 0.5 * 3 * 1.1 v
    v = 2
    assert memory_reward_maximum(reward, v) == pytest.approx(
        (12 * 1.1 * v + 0.5 * 3 * 1.1 * v) ** 2
    )


def test_memory_reward_adds_corner_approaches_to_the_episodes_without_a_tile():
    from mbn.experiments.program_module import MemoryReward, memory_reward_maximum

    reward = MemoryReward(approaches=("south", "west", "east"))
    eps = reward.episodes()
    # south: 27 as above; each corner approach: 4 kinds x 2 memory episodes + 3 rest
    assert len(eps) == 27 + 2 * (4 * 2 + 3)
    corner = [e for e in eps if e[4] != "south"]
    assert all(
        tile is None and seq in ("memory_one", "memory_two", "rest") for _, tile, seq, *_ in corner
    )
    assert {e[4] for e in corner} == {"west", "east"}
    # per rule 12 + 2 * 4 episodes, rest 3 * 3
    assert memory_reward_maximum(reward, 1) == pytest.approx((20 * 1.1 + 0.5 * 9 * 1.1) ** 2)


@pytest.mark.parametrize("approaches", [(), ("north",), ("west", "west")])
def test_memory_reward_rejects_bad_approaches(approaches):
    from mbn.experiments.program_module import MemoryReward

    with pytest.raises(MbnInputError, match="approaches"):
        MemoryReward(approaches=approaches)


def test_priming_shows_a_latch_remembers_and_a_leaky_module_forgets():
    from mbn.experiments.program_module import MemoryReward, camera_inputs, prime

    seqs = MemoryReward().sequences()
    names = ["rest", "after_one", "after_two", "memory_one", "memory_two"]
    inputs = [camera_inputs(seqs[n]) for n in names]
    assert inputs[0].shape == (0, 2)
    assert inputs[3].shape == (round((1.5 + 20 + 1.5 + 50) / 0.1), 2)
    g = PMGenome(3)
    leaky = _switch_latch()
    leaky[[4, 8]] = 0.0  # no self-excitation: the program decays once the tile is out of view
    pm = g.network(jnp.asarray(np.stack([_switch_latch(), leaky])))
    y = np.asarray(prime(pm, inputs))  # (2 networks, 5 sequences, 3 neurons)
    rates = 1.0 / (1.0 + np.exp(-(y + np.asarray(pm.bias)[:, None, :])))
    right, left = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 1.0])
    latch = rates[0]
    for k, name in enumerate(names):
        want = left if name in ("after_two", "memory_two") else right
        np.testing.assert_allclose(latch[k], want, atol=0.02, err_msg=name)
    # the leaky module has forgotten the two-colour tile 50 s later
    np.testing.assert_allclose(rates[1, names.index("memory_two")], right, atol=0.02)


def test_fidelity_costs_a_shifted_program_more_than_the_programs_themselves():
    """With the right- and left-follower riding along, the reward's fidelity term costs a PM
    whose left code is shifted (third value 0.6 instead of 1) more than one that outputs the
    interpreter's programs exactly."""
    import jax

    from mbn.experiments.program_module import MemoryReward, pm_memory_fitness
    from mbn.networks.programmable import differing_connections

    genes = np.asarray(jax.random.uniform(jax.random.key(4), (12,), minval=-1, maxval=1))
    rf = Genome().network(jnp.asarray(genes))
    # LF differs in three connections into neuron 2 so that the programs are RF (1, 0, 0) and
    # LF (0, 1, 1), the codes the hand-made latch puts out
    lf_genes = genes.copy()
    lf_genes[[3, 4, 10]] = genes[[3, 4, 10]] + np.array([-2.0, 2.0, 2.0])
    lf = Genome().network(jnp.asarray(lf_genes))
    im = build_interpreter(rf, differing_connections(rf, lf, margin=0.0), load_default())
    np.testing.assert_allclose(np.asarray(im.program_of(rf)), [1, 0, 0], atol=1e-6)
    np.testing.assert_allclose(np.asarray(im.program_of(lf)), [0, 1, 1], atol=1e-6)
    exact = _switch_latch()
    shifted = exact.copy()
    shifted[8] = 0.0  # neuron 3 no longer holds itself: its left code sags to about 0.6
    population = jnp.asarray(np.stack([exact, shifted]), jnp.float32)
    kw = {"variants": 1, "seconds": 1.5, "references": (rf, lf)}
    small = {"kinds": ("LS",), "rest_kinds": ()}
    plain = pm_memory_fitness(PMGenome(3), im.net, reward=MemoryReward(**small), **kw)
    faithful = pm_memory_fitness(
        PMGenome(3), im.net, reward=MemoryReward(**small, fidelity=0.05), **kw
    )
    before = np.asarray(plain(population))
    share = (before - np.asarray(faithful(population))) / before  # what the fidelity term costs
    assert np.all(before > 0) and np.all(share > 0)
    assert share[1] > share[0] + 0.2
    with pytest.raises(MbnInputError, match="references"):
        pm_memory_fitness(PMGenome(3), im.net, reward=MemoryReward(fidelity=1.0))
    with pytest.raises(MbnInputError, match="fidelity"):
        MemoryReward(fidelity=-1.0)


def test_program_reward_ranks_an_exact_latch_above_a_leaky_one_and_a_slow_one():
    """The program reward (no robot) is near its maximum 0 for the hand-made latch, lower for a
    latch that forgets the two-colour tile once it is out of view, and lower for one that only
    switches after the tile has been in view for longer than ``switch`` seconds; it refuses
    programs of the wrong length."""
    from mbn.experiments.program_module import pm_program_fitness

    g = PMGenome(3)
    exact = _switch_latch()
    leaky = exact.copy()
    leaky[[4, 8]] = 0.0
    slow = exact.copy()
    slow[9:15] *= 0.25  # weak camera inputs: the latch flips seconds after the tile appears
    fit = pm_program_fitness(g, ((1.0, 0.0, 0.0), (0.0, 1.0, 1.0)))
    score = np.asarray(fit(jnp.asarray(np.stack([exact, leaky, slow]), jnp.float32)))
    assert score[0] > -0.01
    assert score[1] < score[0] - 0.05
    assert score[2] < score[0] - 0.005
    assert np.all(score <= 0.0)
    # swapping the programs makes the exact latch the worst possible one
    swapped = pm_program_fitness(g, ((0.0, 1.0, 1.0), (1.0, 0.0, 0.0)))
    assert float(swapped(jnp.asarray(exact[None], jnp.float32))[0]) < -0.9
    with pytest.raises(MbnInputError, match="programs must have 3 values"):
        pm_program_fitness(g, ((1.0, 0.0), (0.0, 1.0)))


def test_a_pm_driving_the_robot_in_mazes_scores_as_its_controller_file_runs(quick_run):
    """``pm_maze_fitness`` runs each genome's PM in the template MBN, started latched after a
    one-colour tile: for the quick run's own PM (whose start settled after 1.5 s + 40 s, the
    fitness's start) its value is the maze fitness of a rollout of the controller file itself;
    each genome's value is its own (alone as in a population), within the episodes' ceiling."""
    import json
    from pathlib import Path

    from mbn.controllers import make_controller, read_controller_spec
    from mbn.experiments.crossroads import F_M_WEIGHT
    from mbn.experiments.maze_task import MazeTask, maze_episode_fitness
    from mbn.experiments.program_module import (
        MAZE_START_SEE,
        MAZE_START_SETTLE,
        pm_maze_fitness,
    )
    from mbn.world.rollout import run_rollout

    folder = Path(quick_run[0])
    template = read_controller_spec(folder / "controllers" / "mbn.json")
    record = json.loads((folder / "stages" / "pm.json").read_text())
    genes = np.asarray(record["best_genome"])
    assert record["initial"]["settled_after_seconds"] == pytest.approx(
        MAZE_START_SEE - 1.5 + MAZE_START_SETTLE
    )
    genome = PMGenome(programs=3, inputs=2)
    task = MazeTask(rule="tiles", family="tiles2", pool=6, mazes=2, starts=2, seconds=30.0)
    fitness = pm_maze_fitness(template, genome, task)
    rng = np.random.default_rng(0)
    population = np.stack([genes, rng.uniform(-10, 10, genes.shape), np.zeros_like(genes)])
    values = np.asarray(fitness(jnp.asarray(population)))
    assert values.shape == (3,)
    assert np.all(values <= task.episodes * (1 + F_M_WEIGHT) + 1e-9)
    np.testing.assert_allclose(np.asarray(fitness(jnp.asarray(population[1:2]))), values[1:2],
                               rtol=1e-6, atol=1e-6)  # fmt: skip

    # the controller file, run as it is, from its recorded start
    loaded = make_controller(template, where="mbn.json")
    arrays = task.arrays()
    stats = run_rollout(
        arrays.world,
        loaded.controller,
        loaded.initial_state(arrays.episodes),
        jnp.asarray(arrays.poses),
        jnp.asarray(arrays.maze_index),
        task.rollout_config(camera=loaded.camera),
        junctions=arrays.junctions,
    ).stats
    own = float(np.sum(np.asarray(maze_episode_fitness(stats, task))))
    assert values[0] == pytest.approx(own, abs=1e-3)

    with pytest.raises(MbnInputError, match="tiles"):
        pm_maze_fitness(template, genome, MazeTask(rule="right", pool=6, mazes=2, starts=2))
    with pytest.raises(MbnInputError, match="program module of 3 neurons"):
        pm_maze_fitness(template, PMGenome(programs=2, inputs=2), task)


@pytest.mark.slow
def test_a_pm_driving_the_robot_in_mazes_runs_under_the_tasks_noise(quick_run):
    """Under the maze task's noise the fitness changes, and the same key gives the same
    values (the noise is drawn from the task's key, inside the compiled fitness)."""
    from pathlib import Path

    import jax

    from mbn.controllers import read_controller_spec
    from mbn.experiments.maze_task import MazeTask
    from mbn.experiments.program_module import pm_maze_fitness
    from mbn.world.sensors import NoiseConfig

    folder = Path(quick_run[0])
    template = read_controller_spec(folder / "controllers" / "mbn.json")
    genome = PMGenome(programs=3, inputs=2)
    genes = np.random.default_rng(1).uniform(-10, 10, (2, genome.size))
    plain = MazeTask(rule="tiles", family="tiles2", pool=6, mazes=2, starts=2, seconds=20.0)
    noise = NoiseConfig(sonar_std=0.05, wheel_std=0.1, camera_miss=0.2)
    noisy = MazeTask(
        rule="tiles", family="tiles2", pool=6, mazes=2, starts=2, seconds=20.0,
        noise=noise, noise_key=jax.random.key(4),
    )  # fmt: skip
    quiet = np.asarray(pm_maze_fitness(template, genome, plain)(jnp.asarray(genes)))
    once = np.asarray(pm_maze_fitness(template, genome, noisy)(jnp.asarray(genes)))
    again = np.asarray(pm_maze_fitness(template, genome, noisy)(jnp.asarray(genes)))
    np.testing.assert_array_equal(once, again)
    assert not np.allclose(once, quiet, atol=1e-6)
