"""The monolithic contender of the three-behaviour task: one CTRNN that reads the sonars' I1..I3
and the camera's tile kinds itself, evolved for every tile's rule at once (the usual alternative
to an MBN, ``docs/contest.md``).

Its genome (:class:`MonolithicGenome`): ``n`` neurons (5 by default) sharing the followers' time
constant; every recurrent weight (``n x n``); the sonar weights of the followers, input k to
neuron k for the first three neurons (the motor neurons are the followers' second and third);
a weight from each tile input to every neuron (``kinds x n``); and a bias per neuron, so that
its neurons can hold the last tile's rule as a program module's do.

Its fitness (:func:`monolithic_fitness`) sums, over the tile kinds, the branch fitness of the
kind's rule on the crossroads with a tile of that kind in the south arm (the program module's
training crossroads, :class:`~mbn.experiments.crossroads.CrossroadTask` ``tile``): from rest
(``variants`` starts per crossroad), and, from each crossroad's start mark, after the network was
shown each other tile kind (``see`` seconds in view, then ``hold`` seconds without: a rule it
must give up for the new one); and, given a ``rest`` task, the crossroads without a tile from
rest, scored by the rule in force before any tile (the first tile kind's, as an MBN starts as
RF). While it is shown a tile before an episode, its sonar inputs are 0 (open space), as the
program module's priming shows it the camera alone.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from mbn.control.ctrnn import NETWORK_SUBSTEPS, CTRNNState, ctrnn_controller, with_tiles
from mbn.controllers.spec import NUM_INPUTS
from mbn.errors import MbnInputError
from mbn.experiments.crossroads import CrossroadTask, TaskArrays
from mbn.experiments.evolve import tile_fitness
from mbn.experiments.program_module import prime
from mbn.networks.ctrnn import CTRNN, make_ctrnn
from mbn.paper import DEFAULT_TAU
from mbn.world.engine import CameraConfig
from mbn.world.rollout import rollout

__all__ = [
    "MonolithicGenome",
    "add_tile_kind",
    "embed_rf",
    "monolithic_fitness",
    "priming_inputs",
]


@dataclass(frozen=True)
class MonolithicGenome:
    """Genes -> an ``neurons``-neuron CTRNN with I1..I3 and ``kinds`` tile inputs (module
    docstring). Gene order: W (row-major, ``n x n``), the three sonar weights WE[k, k], the tile
    weights WE[:, 3:] (row-major, ``n x kinds``), the biases (``n``)."""

    neurons: int = 5
    kinds: int = 3
    tau: float = DEFAULT_TAU

    def __post_init__(self) -> None:
        if self.neurons < NUM_INPUTS:
            raise MbnInputError(
                f"a monolithic controller needs at least {NUM_INPUTS} neurons (the followers' "
                f"three: the sonars' and the motors'), got {self.neurons}"
            )
        if self.kinds < 1:
            raise MbnInputError(f"kinds must be >= 1, got {self.kinds}")
        if not self.tau > 0:
            raise MbnInputError(f"tau must be > 0, got {self.tau}")

    @property
    def size(self) -> int:
        n = self.neurons
        return n * n + NUM_INPUTS + n * self.kinds + n

    def parameters(self, genes: Array) -> tuple[Array, Array, Array]:
        """``(W, WE, bias)`` of shape ``(..., n, n)``, ``(..., n, 3 + kinds)``, ``(..., n)``."""
        genes = jnp.asarray(genes)
        n, m = self.neurons, self.kinds
        batch = genes.shape[:-1]
        at = 0
        W = genes[..., : n * n].reshape(*batch, n, n)
        at = n * n
        sonar = genes[..., at : at + NUM_INPUTS]
        at += NUM_INPUTS
        tiles = genes[..., at : at + n * m].reshape(*batch, n, m)
        at += n * m
        bias = genes[..., at : at + n]
        rows = jnp.zeros((*batch, n, NUM_INPUTS), genes.dtype)
        k = jnp.arange(NUM_INPUTS)
        rows = rows.at[..., k, k].set(sonar)
        return W, jnp.concatenate([rows, tiles], axis=-1), bias

    def batch(self, genes: Array) -> CTRNN:
        """The networks of genes ``(..., size)`` (unvalidated, for fitness)."""
        W, WE, bias = self.parameters(genes)
        shape = bias.shape
        return CTRNN(
            W=W,
            WE=WE,
            tau=jnp.full(shape, self.tau, W.dtype),
            bias=bias,
            gain=jnp.ones(shape, W.dtype),
        )

    def network(self, genes: Array) -> CTRNN:
        """The CTRNN of one genome (validated; for files and reports)."""
        W, WE, bias = self.parameters(jnp.asarray(genes))
        return make_ctrnn(
            np.asarray(W), np.asarray(WE), self.tau, bias=np.asarray(bias), name="monolithic"
        )


def embed_rf(genome: MonolithicGenome, rf: CTRNN) -> np.ndarray:
    """The genes of ``genome`` whose network is RF's on its first three neurons (RF's
    recurrent weights and sonar diagonal; RF's motor neurons are the followers' and so the
    genome's) and reads nothing else: every other weight and bias 0. A network whose tiles have
    no weight yet drives exactly as RF (its other neurons rest at 0 and feed nothing)."""
    n, m = genome.neurons, genome.kinds
    W = np.zeros((n, n))
    W[:NUM_INPUTS, :NUM_INPUTS] = np.asarray(rf.W, float)
    if np.any(np.asarray(rf.bias)) or np.any(np.asarray(rf.gain) != 1):
        raise MbnInputError("embed_rf: RF with biases or gains is not a follower genome's")
    sonar = np.diagonal(np.asarray(rf.WE, float))[:NUM_INPUTS]
    return np.concatenate([W.ravel(), sonar, np.zeros(n * m), np.zeros(n)])


def add_tile_kind(
    population: np.ndarray, genome: MonolithicGenome, key: Array, sigma: float, bound: float
) -> np.ndarray:
    """A population of ``genome`` grown by one tile kind: every member's genes kept, a weight
    from the new tile input to every neuron inserted (Gaussian of ``sigma``, clipped to the
    bounds), as a program module grows by one input."""
    n, m = genome.neurons, genome.kinds
    if population.shape[1] != genome.size:
        raise MbnInputError(
            f"add_tile_kind: a genome of {genome.size} genes, got {population.shape[1]}"
        )
    p = population.shape[0]
    at = n * n + NUM_INPUTS
    tiles = population[:, at : at + n * m].reshape(p, n, m)
    new = np.clip(sigma * np.array(jax.random.normal(key, (p, n, 1)), dtype=float), -bound, bound)
    grown = np.concatenate([tiles, new], axis=2).reshape(p, n * (m + 1))
    return np.concatenate([population[:, :at], grown, population[:, at + n * m :]], axis=1)


def priming_inputs(kinds: int, shown: int, see: float, hold: float, dt: float = 0.1) -> np.ndarray:
    """The inputs a monolithic network is shown before an episode: tile kind ``shown`` (1-based)
    in view for ``see`` seconds, then nothing for ``hold`` seconds; the sonars read 0 all the
    while. ``(steps, 3 + kinds)``, one row per robot step."""
    tile = np.zeros(NUM_INPUTS + kinds, np.float32)
    tile[NUM_INPUTS + shown - 1] = 1.0
    nothing = np.zeros_like(tile)
    rows = [tile] * round(see / dt) + [nothing] * round(hold / dt)
    return np.stack(rows)


def _with_switches(arrays: TaskArrays, priors: int, marks: int) -> TaskArrays:
    """The task's episodes followed by its first ``marks`` (the crossroads' start marks),
    ``priors`` times over: the episodes after another tile was shown."""

    def more(a: np.ndarray | Array) -> np.ndarray:
        a = np.asarray(a)
        return np.concatenate([a, *([a[:marks]] * priors)])

    return dataclasses.replace(
        arrays,
        poses=more(arrays.poses),
        maze_index=more(arrays.maze_index),
        target=more(arrays.target),
        centre=more(arrays.centre),
    )


def monolithic_fitness(
    genome: MonolithicGenome,
    tasks: Sequence[CrossroadTask],
    camera: CameraConfig,
    *,
    see: float = 1.5,
    hold: float = 30.0,
    switches: bool = True,
    rest: CrossroadTask | None = None,
    substeps: int = NETWORK_SUBSTEPS,
) -> Callable[[Array], Array]:
    """A jitted map from a population ``(P, genome.size)`` to fitness ``(P,)``: the summed
    branch fitness over ``tasks`` (one per tile kind, in kind order: ``tasks[k].tile == k +
    1``, each scored by its rule), from rest and, with ``switches``, from each crossroad's start
    mark after each other kind was shown; plus, with a ``rest`` task (no tile), its episodes
    from rest (module docstring)."""
    if len(tasks) != genome.kinds:
        raise MbnInputError(f"{len(tasks)} tasks for a genome of {genome.kinds} tile kinds")
    for k, t in enumerate(tasks):
        if t.tile != k + 1:
            raise MbnInputError(f"task {k} has tile {t.tile}, expected {k + 1}")
    if rest is not None and rest.tile is not None:
        raise MbnInputError(f"the rest task has a tile ({rest.tile}); it must have none")
    dt = tasks[0].dt
    controller = ctrnn_controller(
        dt=dt, substeps=substeps, inputs=with_tiles(genome.kinds), noise=tasks[0].noise
    )
    plans = []
    for k, t in enumerate(tasks):
        base = t.arrays()
        others = [j + 1 for j in range(genome.kinds) if j != k] if switches else []
        marks = len(base.mazes)
        arrays = _with_switches(base, len(others), marks)
        seqs = [priming_inputs(genome.kinds, j, see, hold, dt) for j in others]
        plans.append((t, arrays, base.episodes, marks, seqs, tile_fitness(arrays)))
    if rest is not None:
        arrays = rest.arrays()
        plans.append((rest, arrays, arrays.episodes, 0, [], tile_fitness(arrays)))

    @jax.jit
    def fitness(population: Array) -> Array:
        p, dtype = population.shape[0], population.dtype
        nets = genome.batch(population)
        n = genome.neurons
        total = jnp.zeros((p,), dtype)
        for t, arrays, plain, marks, seqs, scored in plans:
            e = arrays.episodes
            y0 = [jnp.zeros((p, plain, n), dtype)]
            if seqs:
                primed = prime(nets, seqs, dt, substeps)  # (P, S, n)
                y0 += [jnp.repeat(primed[:, s, None], marks, 1) for s in range(len(seqs))]
            y = jnp.concatenate(y0, axis=1).reshape(p * e, n)
            net = jax.tree.map(functools.partial(jnp.repeat, repeats=e, axis=0), nets)
            stats = rollout(
                arrays.world,
                controller,
                CTRNNState(net, y),
                jnp.asarray(np.tile(arrays.poses, (p, 1)), dtype),
                jnp.asarray(np.tile(arrays.maze_index, p)),
                t.rollout_config(camera=camera),
                junctions=arrays.junctions,
                key=t.rollout_key,
            ).stats
            total = total + scored(stats, t).reshape(p, e).sum(-1)
        return total

    return fitness
