"""Evolving wall-following CTRNNs on the crossroad task by Differential Evolution.

A :class:`Genome` says which connections of a 3-neuron CTRNN the genes set (the rest come from a
base network): the paper's RF evolves all 9 recurrent weights and the 3 input weights of
"neuron k receives input k" (12 genes); its LF re-evolves 3 connections of RF. Evolution runs one
generation at a time (:func:`generation`) so that a runner can checkpoint every generation; the
key of generation g is ``fold_in(key, g)``, so a resumed run draws exactly what an uninterrupted
one would.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, ThreadPoolExecutor
from dataclasses import dataclass
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from mbn.control.ctrnn import (
    NETWORK_SUBSTEPS,
    CTRNNState,
    ProgrammedState,
    ctrnn_controller,
    interpreter_controller,
)
from mbn.errors import MbnInputError
from mbn.evolution.de import DEConfig, DEState, ask, init, initialize_fitness, tell
from mbn.experiments.crossroads import CrossroadTask, TaskArrays, episode_fitness, paper_terms
from mbn.experiments.maze_task import MazeTask, maze_episode_fitness
from mbn.host import put
from mbn.networks.ctrnn import CTRNN, make_ctrnn
from mbn.networks.programmable import Connection, Interpreter
from mbn.paper import DEFAULT_TAU
from mbn.world.rollout import (
    EpisodeStats,
    concatenate_states,
    count_robot_steps,
    own_tally,
    rollout,
    run_rollout,
    tally_of,
)

#: A training task: the paper's crossroads, or episodes in mazes of a family.
Task = CrossroadTask | MazeTask

__all__ = [
    "FITNESS_PARTS",
    "RF_CONNECTIONS",
    "Genome",
    "KindFitness",
    "OwnedFitness",
    "connection_group_fitness",
    "connection_search_fitness",
    "crossroad_fitness",
    "crossroad_scores",
    "emulated_fitness",
    "evaluate_interpreted",
    "evaluate_networks",
    "generation",
    "interpreter_programs",
    "kind_fitness",
    "perturbations",
    "robust_fitness",
    "set_connections",
    "split_fitness",
    "start",
]

#: Shared time constant of the RF/LF neurons (the paper gives none; docs/experiments.md).
#: The RF genome: all recurrent weights, then WE[k, k] (neuron k receives input k).
RF_CONNECTIONS: tuple[Connection, ...] = tuple(
    Connection("W", i, j) for i in range(3) for j in range(3)
) + tuple(Connection("WE", k, k) for k in range(3))


@dataclass(frozen=True)
class Genome:
    """Genes -> a 3-neuron CTRNN: ``connections[g]`` is set to gene g, everything else is
    ``base``'s (zeros by default); time constants ``tau``."""

    connections: tuple[Connection, ...] = RF_CONNECTIONS
    base_W: tuple[tuple[float, ...], ...] = ((0.0,) * 3,) * 3
    base_WE: tuple[tuple[float, ...], ...] = ((0.0,) * 3,) * 3
    tau: float = DEFAULT_TAU

    def __post_init__(self) -> None:
        if not self.connections:
            raise MbnInputError("a genome needs at least one connection")
        for c in self.connections:
            if c.i >= 3 or c.j >= 3:
                raise MbnInputError(f"connection {c}: out of range for 3 neurons and 3 inputs")
        if not self.tau > 0:
            raise MbnInputError(f"tau must be > 0, got {self.tau}")

    @classmethod
    def around(cls, base: CTRNN, connections: tuple[Connection, ...]) -> Genome:
        """Genes for ``connections`` of ``base``; the other weights stay ``base``'s."""
        W = np.asarray(base.W, dtype=float)
        WE = np.asarray(base.WE, dtype=float)
        return cls(
            connections=connections,
            base_W=tuple(map(tuple, W.tolist())),
            base_WE=tuple(map(tuple, WE.tolist())),
            tau=float(np.asarray(base.tau).reshape(-1)[0]),
        )

    @property
    def size(self) -> int:
        return len(self.connections)

    def weights(self, genes: Array) -> tuple[Array, Array]:
        """``(W, WE)`` of shape ``(..., 3, 3)`` for genes ``(..., size)``."""
        genes = jnp.asarray(genes)
        batch = genes.shape[:-1]
        W = jnp.broadcast_to(jnp.asarray(self.base_W, genes.dtype), (*batch, 3, 3))
        WE = jnp.broadcast_to(jnp.asarray(self.base_WE, genes.dtype), (*batch, 3, 3))
        for g, c in enumerate(self.connections):
            if c.kind == "W":
                W = W.at[..., c.i, c.j].set(genes[..., g])
            else:
                WE = WE.at[..., c.i, c.j].set(genes[..., g])
        return W, WE

    def network(self, genes: Array) -> CTRNN:
        """The CTRNN of one genome (validated; for files and reports). Made on the host: the
        same weights as :meth:`weights`, without an eager program to compile."""
        values = np.asarray(genes)
        W = np.array(self.base_W, values.dtype)
        WE = np.array(self.base_WE, values.dtype)
        for g, c in enumerate(self.connections):
            (W if c.kind == "W" else WE)[c.i, c.j] = values[g]
        return make_ctrnn(W, WE, self.tau)

    def genes_of(self, net: CTRNN) -> np.ndarray:
        """The genes that reproduce ``net``'s chosen connections."""
        return np.array([float(c.value(net)) for c in self.connections])


def evaluate_networks(
    W: Array,
    WE: Array,
    tau: float,
    arrays: TaskArrays,
    task: Task,
    substeps: int = NETWORK_SUBSTEPS,
    poses: Array | None = None,
) -> EpisodeStats:
    """Run every network ``(N, 3, 3)`` on every episode of the task (``substeps`` Euler steps per
    robot step): stats of shape ``(N * E,)``, network-major. ``poses`` ``(N * E, 3)``: each
    robot's start (default the task's episodes' starts for every network)."""
    n, e = W.shape[0], arrays.episodes
    W = jnp.repeat(W, e, 0)
    WE = jnp.repeat(WE, e, 0)
    dtype = W.dtype
    net = CTRNN(
        W=W,
        WE=WE,
        tau=jnp.full((n * e, 3), tau, dtype),
        bias=jnp.zeros((n * e, 3), dtype),
        gain=jnp.ones((n * e, 3), dtype),
    )
    controller = ctrnn_controller(dt=task.dt, substeps=substeps, noise=task.noise)
    state = CTRNNState(net, jnp.zeros((n * e, 3), dtype))
    return _episodes(controller, state, n, dtype, arrays, task, poses)


def _episodes(
    controller: Callable[[Any, Any], tuple[Any, tuple[Array, Array]]],
    state: Any,
    n: int,
    dtype: Any,
    arrays: TaskArrays,
    task: Task,
    poses: Array | None = None,
) -> EpisodeStats:
    """Run ``n`` controllers (batched ``state``, network-major) on every episode of the task
    (from ``poses`` ``(n * E, 3)`` where given, else from the task's starts)."""
    if poses is None:
        poses = jnp.tile(jnp.asarray(arrays.poses, dtype), (n, 1))
    return rollout(
        arrays.world,
        controller,
        state,
        jnp.asarray(poses, dtype),
        jnp.tile(jnp.asarray(arrays.maze_index), n),
        task.rollout_config(),
        junctions=arrays.junctions,
        key=task.rollout_key,
    ).stats


#: Task fields a compiled fitness takes as arrays, not as static settings: the noise key, and
#: the seed of the jittered starts and a maze task's draw (the starts themselves are arrays), so
#: that the seeds of a sweep, and a maze task's draws, share one program.
_ARRAY_FIELDS = ("noise_key", "seed", "draw")


@dataclass(frozen=True)
class _Episodes:
    """The static part of a crossroad task's episodes, as a compiled fitness takes it: the
    task's settings but :data:`_ARRAY_FIELDS` (a (name, value) tuple, hashable) and the arrays'
    scalars. The arrays themselves (:func:`_episode_arrays`) are arguments, so that one program
    serves every base network, every choice of connections, every noise key and every seed's
    starts."""

    task: tuple[tuple[str, Any], ...]
    cell: float
    arm_length: float
    maze: bool = False  # a MazeTask (else a CrossroadTask)

    @classmethod
    def of(cls, task: Task, arrays: TaskArrays) -> _Episodes:
        fields = tuple(
            (f.name, getattr(task, f.name))
            for f in dataclasses.fields(task)
            if f.name not in _ARRAY_FIELDS
        )
        return cls(fields, float(arrays.cell), float(arrays.arm_length), isinstance(task, MazeTask))

    def rebuild(self, dynamic: dict[str, Any]) -> tuple[Task, TaskArrays]:
        """The task (with the noise key of ``dynamic``; its start seed the default, unused: the
        starts are ``dynamic``'s) and its arrays, inside a trace."""
        kind: type[CrossroadTask] | type[MazeTask] = MazeTask if self.maze else CrossroadTask
        task = kind(**dict(self.task), noise_key=dynamic["key"])
        arrays = TaskArrays(
            mazes=[],
            world=dynamic["world"],
            junctions=dynamic["junctions"],
            poses=dynamic["poses"],
            maze_index=dynamic["maze_index"],
            target=dynamic["target"],
            centre=dynamic["centre"],
            cell=self.cell,
            arm_length=self.arm_length,
        )
        return task, arrays


def _episode_arrays(task: Task, arrays: TaskArrays) -> dict[str, Any]:
    """The arrays of a task's episodes, as a compiled fitness takes them (:class:`_Episodes`)."""
    return {
        "world": arrays.world,
        "junctions": arrays.junctions,
        "poses": np.asarray(arrays.poses),
        "maze_index": np.asarray(arrays.maze_index),
        "target": np.asarray(arrays.target),
        "centre": np.asarray(arrays.centre),
        "key": task.rollout_key,
    }


def _fitness_of(
    population: Array,
    base_W: Array,
    base_WE: Array,
    is_input: Array,
    rows: Array,
    cols: Array,
    dynamic: dict[str, Any],
    episodes: _Episodes,
    tau: float,
    poses: Array | None = None,
) -> Array:
    task, arrays = episodes.rebuild(dynamic)
    W, WE = set_connections(base_W, base_WE, population, is_input, rows, cols)
    stats = evaluate_networks(W, WE, tau, arrays, task, poses=poses)
    per_episode = tile_fitness(arrays)(stats, task)
    return per_episode.reshape(population.shape[0], arrays.episodes).sum(-1)


@partial(jax.jit, static_argnames=("episodes", "tau"))
def _owned_fitness(
    population: Array,
    owner: Array,
    base_W: Array,
    base_WE: Array,
    is_input: Array,
    rows: Array,
    cols: Array,
    noise: Array,
    poses: Array,
    dynamic: dict[str, Any],
    *,
    episodes: _Episodes,
    tau: float,
) -> Array:
    """Fitness ``(P,)`` of genomes that each belong to an owner ``owner[i]`` (a DE run of a
    group, or a seed of a batched sweep) and set its connections (row ``owner[i]`` of
    ``is_input, rows, cols``, ``(R, G)``) of its base network (``base_W, base_WE``,
    ``(R, 3, 3)``, :func:`set_connections`), started from its episodes' poses (``(R, E, 3)``),
    summed over the task's episodes and averaged over the genome and its perturbed copies
    ``genome + noise[owner[i], k]`` (``noise`` ``(R, K, G)``; ``K = 0``: the genome alone). One
    compiled program per task, time constant and shapes in a process. Each genome's value
    depends on its own row only: evaluated in any batch, whole or in parts, it is the same bit
    for bit (``tests/experiments/test_batching.py``), which lets a sweep batch its seeds."""
    copies = noise.shape[1]
    if copies:
        d = population.shape[1]
        shifted = population[None] + jnp.swapaxes(noise[owner], 0, 1).astype(population.dtype)
        population = jnp.concatenate([population, shifted.reshape(-1, d)])
        owner = jnp.tile(owner, copies + 1)
    start = poses[owner].reshape(-1, 3)
    dynamic = {**dynamic, "poses": poses[0]}  # the episodes' count and layout
    values = _fitness_of(
        population,
        base_W[owner],
        base_WE[owner],
        is_input[owner],
        rows[owner],
        cols[owner],
        dynamic,
        episodes,
        tau,
        start,
    )
    return values.reshape(copies + 1, -1).mean(0) if copies else values


def _counted(population: Array, arrays: TaskArrays, task: Task) -> None:
    count_robot_steps(int(population.shape[0]) * arrays.episodes * task.steps)


def _fingerprint(tree: Any) -> str:
    """A digest of the arrays of a pytree (shapes, dtypes and bytes), to tell equal tasks."""
    digest = hashlib.sha256()
    for leaf in jax.tree.leaves(tree):
        if jnp.issubdtype(jnp.asarray(leaf).dtype, jax.dtypes.prng_key):
            leaf = jax.random.key_data(leaf)
        a = np.asarray(leaf)
        digest.update(f"{a.shape}{a.dtype}".encode())
        digest.update(np.ascontiguousarray(a).tobytes())
    return digest.hexdigest()


@dataclass(frozen=True, eq=False)
class OwnedFitness:
    """A population fitness on the crossroads whose genomes each belong to an owner:
    ``fitness(population, owner=None)`` (``owner`` ``(P,)``, default all 0) is
    :func:`_owned_fitness` with the owners' rows of :attr:`owned` (base weights, connections,
    perturbations, starts) and the task's other arrays. Made by :func:`crossroad_fitness`,
    :func:`connection_group_fitness` and :func:`robust_fitness`.

    Fitnesses of equal :attr:`signature` (the same task but for its starts, the same time
    constant and shapes) are one program: :meth:`merged` evaluates the populations of several
    (the seeds of a batched sweep, ``mbn.experiments.batching``) in one call, each genome with
    its own owner's rows, and gives each the values it would get alone."""

    owned: tuple[np.ndarray, ...]  # base_W, base_WE, is_input, rows, cols, noise, poses: (R, ...)
    dynamic: dict[str, Any]  # the task's arrays but its starts
    episodes: _Episodes
    tau: float
    steps_per_episode: int  # robot-steps of one episode
    fingerprint: str  # of ``dynamic`` (:func:`_fingerprint`)

    @property
    def signature(self) -> tuple[Any, ...]:
        """What fitnesses merged into one call share: the task but its starts, the time
        constant, and the owned arrays' shapes but the owners'."""
        shapes = tuple((a.shape[1:], str(a.dtype)) for a in self.owned)
        return (self.episodes, self.tau, shapes, self.fingerprint)

    @property
    def steps_per_genome(self) -> int:
        """Robot-steps of one genome and its perturbed copies."""
        episodes = self.owned[6].shape[1]
        return (self.owned[5].shape[1] + 1) * episodes * self.steps_per_episode

    @classmethod
    def make(
        cls,
        base_W: np.ndarray,
        base_WE: np.ndarray,
        tables: Sequence[np.ndarray],
        noise: np.ndarray,
        task: Task,
        arrays: TaskArrays,
        tau: float,
    ) -> OwnedFitness:
        dynamic = _episode_arrays(task, arrays)
        poses = dynamic.pop("poses")
        r = base_W.shape[0]
        owned = (
            np.asarray(base_W, np.float64),
            np.asarray(base_WE, np.float64),
            *(np.asarray(t) for t in tables),
            np.asarray(noise),
            np.broadcast_to(poses, (r, *poses.shape)).copy(),
        )
        return cls(
            owned=owned,
            dynamic=dynamic,
            episodes=_Episodes.of(task, arrays),
            tau=float(tau),
            steps_per_episode=task.steps,
            fingerprint=_fingerprint(dynamic),
        )

    @property
    def owners(self) -> int:
        return int(self.owned[0].shape[0])

    def with_noise(self, noise: np.ndarray) -> OwnedFitness:
        """The same fitness averaged over each genome and its copies ``genome + noise[k]``
        (``noise`` ``(K, G)``, the same for every owner)."""
        noise = np.asarray(noise)
        if noise.ndim != 2 or noise.shape[1] != self.owned[5].shape[2]:
            raise MbnInputError(
                f"perturbations of shape {noise.shape} for genomes of {self.owned[5].shape[2]}"
            )
        if self.owned[5].shape[1]:
            raise MbnInputError("this fitness already averages over perturbed copies")
        stacked = np.broadcast_to(noise, (self.owners, *noise.shape)).copy()
        return dataclasses.replace(self, owned=(*self.owned[:5], stacked, self.owned[6]))

    def count(self, genomes: int) -> None:
        """Count the robot-steps of evaluating ``genomes`` genomes (on this thread's tally)."""
        count_robot_steps(genomes * self.steps_per_genome)

    def __call__(self, population: Array, owner: Any = None) -> Array:
        population = jnp.asarray(population)
        self.count(int(population.shape[0]))
        if owner is None:
            owner = np.zeros(population.shape[0], np.int32)
        return self.evaluate(population, owner, self.owned)

    def evaluate(self, population: Any, owner: Any, owned: tuple[Any, ...]) -> Array:
        """The values of ``population`` whose genomes take rows ``owner`` of ``owned`` (this
        fitness's, or those of several merged, :meth:`merged`); nothing is counted."""
        population = jnp.asarray(population)
        dtype = population.dtype
        base_W, base_WE, is_input, rows, cols, noise, poses = owned
        return _owned_fitness(
            population,
            put(owner, np.int32),
            put(base_W, dtype),
            put(base_WE, dtype),
            put(is_input),
            put(rows, np.int32),
            put(cols, np.int32),
            put(noise, dtype),
            put(poses, dtype),
            self.dynamic,
            episodes=self.episodes,
            tau=self.tau,
        )

    @staticmethod
    def merged(
        requests: Sequence[tuple[OwnedFitness, np.ndarray, np.ndarray]],
    ) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
        """``(population, owner, owned)`` of several fitnesses of one signature and their
        populations and owners, joined: the owners of request k are renumbered after those of
        the requests before it."""
        signatures = {f.signature for f, _, _ in requests}
        if len(signatures) != 1:
            raise MbnInputError("fitnesses of different tasks or shapes cannot be merged")
        offsets = np.cumsum([0] + [f.owners for f, _, _ in requests])
        population = np.concatenate([np.asarray(p) for _, p, _ in requests])
        owner = np.concatenate([np.asarray(o) + offsets[k] for k, (_, _, o) in enumerate(requests)])
        owned = tuple(
            np.concatenate([f.owned[i] for f, _, _ in requests])
            for i in range(len(requests[0][0].owned))
        )
        return population, owner, owned


class Redrawn:
    """A fitness whose episodes are drawn again every ``every`` generations (``docs/
    generalization.md``): generation ``g`` (0 is the first population's evaluation) is judged
    by ``make(draw(g))``, ``draw(g) = g // every`` (``every`` 0: never, always draw 0).
    :meth:`mbn.experiments.pipeline.context.StageContext.evolve_group` judges the populations
    on the new episodes where the draw changes, before that generation's trials. The fitness of
    a draw is made once (the last draw's is kept)."""

    def __init__(self, make: Callable[[int], Any], every: int) -> None:
        if not (isinstance(every, int) and not isinstance(every, bool) and every >= 0):
            raise MbnInputError(f"redraw every must be an integer >= 0, got {every!r}")
        self.make = make
        self.every = every
        self._held: tuple[int, Any] | None = None

    def draw(self, generation: int) -> int:
        return 0 if self.every == 0 else int(generation) // self.every

    def at(self, generation: int) -> Any:
        """The fitness of generation ``generation``'s episodes."""
        draw = self.draw(generation)
        if self._held is None or self._held[0] != draw:
            self._held = (draw, self.make(draw))
        return self._held[1]


def crossroad_fitness(genome: Genome, task: Task, arrays: TaskArrays | None = None) -> OwnedFitness:
    """A compiled map from a population ``(P, genome.size)`` to fitness ``(P,)`` (sum over the
    task's episodes). The genome's base weights and the task's arrays are arguments of one
    program per task and shapes (:func:`_owned_fitness`): every genome of the same length,
    around any base network, reuses it."""
    arrays = arrays or task.arrays()
    base_W = np.asarray(genome.base_W, np.float64)[None]
    base_WE = np.asarray(genome.base_WE, np.float64)[None]
    tables = [np.asarray(t)[None] for t in _connection_tables(genome.connections, genome.size)]
    noise = np.zeros((1, 0, genome.size))
    return OwnedFitness.make(base_W, base_WE, tables, noise, task, arrays, genome.tau)


@partial(jax.jit, static_argnames=("episodes", "tau"))
def _network_terms(
    W: Array, WE: Array, dynamic: dict[str, Any], *, episodes: _Episodes, tau: float
) -> dict[str, Array]:
    task, arrays = episodes.rebuild(dynamic)
    stats = evaluate_networks(W[None], WE[None], tau, arrays, task)
    terms = paper_terms(stats)
    return {
        "branch_fitness": jnp.sum(tile_fitness(arrays)(stats, task)),
        "paper_F_M": jnp.sum(terms["F_M"]),
        "paper_F_R": jnp.sum(terms["F_R"]),
        "paper_F_L": jnp.sum(terms["F_L"]),
    }


def crossroad_scores(
    net: CTRNN, task: CrossroadTask, arrays: TaskArrays | None = None
) -> dict[str, float]:
    """A network's branch fitness summed over the task's episodes and the paper's F_M, F_R,
    F_L (:func:`mbn.experiments.crossroads.paper_terms`) summed likewise: one compiled program
    per task in a process."""
    arrays = arrays or task.arrays()
    W, WE = jnp.asarray(net.W), jnp.asarray(net.WE)
    _counted(W[None], arrays, task)
    values = _network_terms(
        W,
        WE,
        _episode_arrays(task, arrays),
        episodes=_Episodes.of(task, arrays),
        tau=float(np.asarray(net.tau).reshape(-1)[0]),
    )
    return {k: float(v) for k, v in values.items()}


def perturbations(key: Array, copies: int, size: int, sigma: float) -> Array:
    """``copies`` fixed perturbations of a genome of ``size`` genes, normal with deviation
    ``sigma`` (drawn once from ``key``: every evaluation of a run sees the same ones, so the
    fitness stays deterministic and DE's greedy replacement stays fair)."""
    if copies < 0 or not sigma >= 0:
        raise MbnInputError(
            f"perturbations: need copies >= 0 and sigma >= 0, got {copies}, {sigma}"
        )
    return _scaled_normal(key, float(sigma), (copies, size))


@partial(jax.jit, static_argnames="shape")
def _scaled_normal(key: Array, sigma: float, shape: tuple[int, int]) -> Array:
    return sigma * jax.random.normal(key, shape)


def robust_fitness(fitness: Callable[..., Array], noise: Array) -> Callable[..., Array]:
    """``fitness`` averaged over each genome and its perturbed copies ``genome + noise[k]``.

    Networks evolved this way keep their behaviour when their weights move by about ``sigma``,
    which is what the interpreter does to them: its trained multipliers are off by up to 0.008,
    times the range of the programmable weight (``docs/reproduce.md``). With no perturbation
    (``noise`` of shape ``(0, size)``) it is ``fitness`` itself. One call evaluates all copies
    in one batch. Arrays after the population (one row per genome) go with each copy.
    """
    if isinstance(fitness, OwnedFitness):
        return fitness if np.shape(noise)[0] == 0 else fitness.with_noise(np.asarray(noise))
    noise = jnp.asarray(noise)
    copies = noise.shape[0]
    if copies == 0:
        return fitness

    def averaged(population: Array, *per_genome: Array) -> Array:
        d = population.shape[1]
        if noise.shape[1] != d:
            raise MbnInputError(f"perturbations of {noise.shape[1]} genes for genomes of {d}")
        tiled = (_tiled(jnp.asarray(x), copies + 1) for x in per_genome)
        values = fitness(_with_copies(population, noise), *tiled)
        return _mean_of_copies(values, copies + 1)

    return averaged


@jax.jit
def _with_copies(population: Array, noise: Array) -> Array:
    """The genomes ``(P, d)`` and then their perturbed copies, copy by copy: ``((K+1) P, d)``."""
    d = population.shape[1]
    shifted = (population[None] + noise[:, None].astype(population.dtype)).reshape(-1, d)
    return jnp.concatenate([population, shifted])


@partial(jax.jit, static_argnames="times")
def _tiled(x: Array, times: int) -> Array:
    return jnp.tile(x, (times,) + (1,) * (x.ndim - 1))


@partial(jax.jit, static_argnames="times")
def _mean_of_copies(values: Array, times: int) -> Array:
    return values.reshape(times, -1).mean(0)


#: A population is always evaluated in this many parts (:func:`split_fitness`), however many
#: threads evaluate them, so that the parts, not the machine, fix the shapes a seed runs on. (An
#: earlier version found a population of 18 evaluated whole and in two halves to differ in the
#: sixth digit; with today's fitness program and XLA the rows come out alike in any batch, bit
#: for bit, which ``mbn sweep --batched`` relies on and ``tests/experiments/test_batching.py``
#: checks; the fixed parts are kept, as they cost nothing.)
FITNESS_PARTS = 2


def split_fitness(
    fitness: Callable[..., Array],
    workers: int,
    pool: Executor | None = None,
    parts: int = FITNESS_PARTS,
) -> Callable[..., Array]:
    """``fitness`` of a population computed in ``parts`` parts (contiguous, as equal as they
    can be), ``min(workers, parts)`` of them at once in threads: each genome's fitness depends on
    its own episodes only, and XLA runs one computation on about one core, so parts evaluated
    side by side use the cores. The parts are the same for any ``workers``, so the values are
    too, bit for bit (a test compares them); ``workers <= 1`` evaluates them one after the
    other. ``parts <= 1``: ``fitness`` itself. Arrays after the population (one row per genome,
    e.g. which DE run of a group it belongs to) are cut into the same parts."""
    if parts <= 1:
        return fitness
    threads = max(1, min(workers, parts))
    executor = pool or (fitness_pool(threads) if threads > 1 else None)

    def parted(population: Array, *per_genome: Array) -> Array:
        p = int(population.shape[0])
        bounds = tuple(int(b) for b in np.linspace(0, p, min(parts, p) + 1).round())
        columns = [split_rows(jnp.asarray(x), bounds) for x in (population, *per_genome)]
        pieces = list(zip(*columns, strict=True))
        if executor is None or threads == 1:
            values = [fitness(*x) for x in pieces]
        else:
            values = [f.result() for f in [executor.submit(fitness, *x) for x in pieces]]
        return join_rows(tuple(jnp.asarray(v) for v in values))

    return parted


def fitness_pool(threads: int) -> ThreadPoolExecutor:
    """Threads that evaluate parts of a population for this thread: they count their
    robot-steps on its tally (:func:`~mbn.world.rollout.own_tally`)."""
    return ThreadPoolExecutor(
        threads, thread_name_prefix="mbn-fitness", initializer=own_tally, initargs=(tally_of(),)
    )


def split_rows(x: Array, bounds: tuple[int, ...]) -> tuple[Array, ...]:
    """``x`` cut along its first axis at ``bounds`` (``(0, ..., len)``): ``x[a:b]`` for each
    pair, cut on the host (genes and fitness values: small arrays; an eager slice would compile
    a program for each shape)."""
    host = np.asarray(x)
    return tuple(put(host[a:b]) for a, b in itertools.pairwise(bounds))


def join_rows(parts: tuple[Array, ...]) -> Array:
    """Arrays joined along their first axis, on the host (as :func:`split_rows`)."""
    return put(np.concatenate([np.asarray(p) for p in parts]))


def set_connections(
    base_W: Array, base_WE: Array, genes: Array, is_input: Array, rows: Array, cols: Array
) -> tuple[Array, Array]:
    """``(W, WE)`` ``(P, 3, 3)``: the base weights with connection g (``WE`` when
    ``is_input[g]``, else ``W``; at ``rows[g], cols[g]``) set to ``genes[:, g]``. The connections
    are arrays, not constants, so one compiled function serves every choice of connections; they
    are ``(G,)`` (the same for every genome) or ``(P, G)`` (one choice per genome)."""
    p, n_genes = genes.shape
    is_input, rows, cols = (
        jnp.broadcast_to(jnp.asarray(a), (p, n_genes)) for a in (is_input, rows, cols)
    )
    W = jnp.broadcast_to(base_W.astype(genes.dtype), (p, 3, 3))
    WE = jnp.broadcast_to(base_WE.astype(genes.dtype), (p, 3, 3))
    idx = jnp.arange(3)
    for g in range(n_genes):
        at = (rows[:, g, None, None] == idx[:, None]) & (cols[:, g, None, None] == idx[None, :])
        into_we = is_input[:, g, None, None]
        value = genes[:, g, None, None]
        W = jnp.where(at & ~into_we, value, W)
        WE = jnp.where(at & into_we, value, WE)
    return W, WE


def _connection_tables(connections: Sequence[Connection], width: int) -> tuple[Array, ...]:
    """``(is_input, rows, cols)`` of ``connections`` for genomes of ``width`` genes, refusing a
    choice that does not fit 3 neurons and 3 inputs."""
    if len(connections) != width:
        raise MbnInputError(f"{len(connections)} connections for genomes of {width} genes")
    for c in connections:
        if c.i >= 3 or c.j >= 3:
            raise MbnInputError(f"connection {c}: out of range for 3 neurons and 3 inputs")
    return (
        put([c.kind == "WE" for c in connections]),
        put([c.i for c in connections], np.int32),
        put([c.j for c in connections], np.int32),
    )


def connection_search_fitness(
    base: CTRNN, task: CrossroadTask, arrays: TaskArrays | None = None
) -> Callable[[Array, tuple[Connection, ...]], Array]:
    """Fitness of populations that re-evolve a few connections of ``base`` (as
    :func:`crossroad_fitness` with ``Genome.around(base, connections)``), compiled once for all
    choices of the same number of connections: ``fitness(population, connections)``."""
    arrays = arrays or task.arrays()

    def fitness(population: Array, connections: tuple[Connection, ...]) -> Array:
        _connection_tables(connections, int(np.shape(population)[1]))  # one line if they differ
        return connection_group_fitness(base, task, [connections], arrays)(population)

    return fitness


def connection_group_fitness(
    base: CTRNN,
    task: Task,
    choices: Sequence[tuple[Connection, ...]],
    arrays: TaskArrays | None = None,
) -> OwnedFitness:
    """:func:`connection_search_fitness` of a group of populations, one per choice of
    connections, evaluated as one batch: ``fitness(population, owner)``, genome ``i`` re-evolving
    ``choices[owner[i]]`` (a group of DE runs, :meth:`StageContext.evolve_group`)."""
    arrays = arrays or task.arrays()
    widths = {len(c) for c in choices}
    if len(widths) != 1:
        raise MbnInputError(f"choices of {sorted(widths)} connections: one size expected")
    ((width,),) = (tuple(widths),)
    tables = [_connection_tables(c, width) for c in choices]
    stacked = [np.stack([np.asarray(t[k]) for t in tables]) for k in range(3)]
    r = len(choices)
    base_W = np.broadcast_to(np.asarray(base.W, np.float64), (r, 3, 3)).copy()
    base_WE = np.broadcast_to(np.asarray(base.WE, np.float64), (r, 3, 3)).copy()
    tau = float(np.asarray(base.tau).reshape(-1)[0])
    noise = np.zeros((r, 0, width))
    return OwnedFitness.make(base_W, base_WE, stacked, noise, task, arrays, tau)


def tile_fitness(arrays: TaskArrays) -> Callable[[EpisodeStats, Task], Array]:
    def f(stats: EpisodeStats, task: Task) -> Array:
        if isinstance(task, MazeTask):  # judged by its junction passes, episode by episode
            return maze_episode_fitness(stats, task)
        n = stats.final_pose.shape[0] // arrays.episodes
        tiled = TaskArrays(
            mazes=arrays.mazes,
            world=arrays.world,
            junctions=arrays.junctions,
            poses=jnp.tile(jnp.asarray(arrays.poses), (n, 1)),
            maze_index=jnp.tile(jnp.asarray(arrays.maze_index), n),
            target=jnp.tile(jnp.asarray(arrays.target), (n, 1)),
            centre=jnp.tile(jnp.asarray(arrays.centre), (n, 1)),
            cell=arrays.cell,
            arm_length=arrays.arm_length,
        )
        return episode_fitness(stats, tiled, task)

    return f


def start(
    key: Array,
    config: DEConfig,
    fitness: Callable[[Array], Array],
    population: np.ndarray | None = None,
) -> DEState:
    """Generation 0: the initial population (drawn from ``fold_in(key, 0)`` unless given) and its
    fitness."""
    from mbn.evolution.de import from_population

    state = (
        init(jax.random.fold_in(key, 0), config)
        if population is None
        else from_population(jnp.asarray(population), config)
    )
    return initialize_fitness(state, fitness(state.population), config)


def generation(
    key: Array, g: int, state: DEState, config: DEConfig, fitness: Callable[[Array], Array]
) -> DEState:
    """Generation ``g >= 1`` of DE/best/1/bin (its key is ``fold_in(key, g)``)."""
    if g < 1:
        raise MbnInputError(f"generation index must be >= 1, got {g}")
    trials = ask(jax.random.fold_in(key, g), state, config)
    return tell(state, trials, fitness(trials), config)


def interpreter_programs(
    template: Interpreter,
    W: Array,
    WE: Array,
    lower: Array | None = None,
    upper: Array | None = None,
) -> tuple[CTRNN, Array]:
    """The interpreter of networks ``(W, WE)`` (batched ``(..., n, n)``, ``(..., n, m)``) built
    on ``template``'s wiring and bounds, and each network's program.

    The interpreter's original block takes the networks' weights, except that a programmable
    connection keeps its direct weight ``min`` (eq. 2); its multipliers and bounds are the
    template's. Programs are ``(w - min) / (max - min)`` clipped to [0, 1].
    """
    n, m = template.num_original, template.num_data_inputs
    batch = W.shape[:-2]
    net = template.net
    full_W = jnp.broadcast_to(net.W.astype(W.dtype), (*batch, *net.W.shape))
    full_WE = jnp.broadcast_to(net.WE.astype(W.dtype), (*batch, *net.WE.shape))
    full_W = full_W.at[..., :n, :n].set(W)
    full_WE = full_WE.at[..., :n, :m].set(WE)
    programs = []
    for c, conn in enumerate(template.connections):
        lo = template.lower[c].astype(W.dtype) if lower is None else lower[..., c]
        hi = template.upper[c].astype(W.dtype) if upper is None else upper[..., c]
        out = template.mul_block(c).start + template.mul_output
        full_W = full_W.at[..., conn.i, out].set(jnp.broadcast_to(hi - lo, batch))
        lo = jnp.broadcast_to(lo, batch)
        hi = jnp.broadcast_to(hi, batch)
        if conn.kind == "W":
            value = W[..., conn.i, conn.j]
            full_W = full_W.at[..., conn.i, conn.j].set(lo)
        else:
            value = WE[..., conn.i, conn.j]
            full_WE = full_WE.at[..., conn.i, conn.j].set(lo)
        programs.append(jnp.clip((value - lo) / (hi - lo), 0.0, 1.0))
    shape = (*batch, net.num_neurons)
    interp = CTRNN(
        W=full_W,
        WE=full_WE,
        tau=jnp.broadcast_to(net.tau.astype(W.dtype), shape),
        bias=jnp.broadcast_to(net.bias.astype(W.dtype), shape),
        gain=jnp.broadcast_to(net.gain.astype(W.dtype), shape),
    )
    return interp, jnp.stack(programs, -1)


def evaluate_interpreted(
    template: Interpreter,
    W: Array,
    WE: Array,
    arrays: TaskArrays,
    task: Task,
    substeps: int = NETWORK_SUBSTEPS,
    lower: Array | None = None,
    upper: Array | None = None,
) -> EpisodeStats:
    """Like :func:`evaluate_networks`, but each network runs as the interpreter programmed with
    it (multipliers and all): stats ``(N * E,)``, network-major. ``lower``/``upper`` ``(N, K)``
    give each network's interpreter its own bounds (default: the template's)."""
    e = arrays.episodes
    W = jnp.repeat(W, e, 0)
    WE = jnp.repeat(WE, e, 0)
    if lower is not None and upper is not None:
        lower, upper = jnp.repeat(lower, e, 0), jnp.repeat(upper, e, 0)
    net, program = interpreter_programs(template, W, WE, lower, upper)
    n = W.shape[0]
    controller = interpreter_controller(dt=task.dt, substeps=substeps, noise=task.noise)
    state = ProgrammedState(net, jnp.zeros((n, template.num_neurons), W.dtype), program)
    return _episodes(controller, state, n // e, W.dtype, arrays, task)


def emulated_fitness(
    genome: Genome,
    template: Interpreter,
    task: Task,
    arrays: TaskArrays | None = None,
    *,
    substeps: int = NETWORK_SUBSTEPS,
) -> Callable[[Array], Array]:
    """Fitness of a population as the smaller of two: the networks themselves, and the
    interpreter programmed with them. Evolution then finds networks that the fixed-weight
    interpreter, with its trained multipliers, really emulates."""
    arrays = arrays or task.arrays()
    tiled = tile_fitness(arrays)

    @jax.jit
    def fitness(population: Array) -> Array:
        W, WE = genome.weights(population)
        plain = evaluate_networks(W, WE, genome.tau, arrays, task)
        emulated = evaluate_interpreted(template, W, WE, arrays, task, substeps)
        p = population.shape[0]
        f_plain = tiled(plain, task).reshape(p, arrays.episodes).sum(-1)
        f_emulated = tiled(emulated, task).reshape(p, arrays.episodes).sum(-1)
        return jnp.minimum(f_plain, f_emulated)

    return fitness


@dataclass(frozen=True, eq=False)
class KindFitness:
    """The fitness of genomes of a controller kind (:mod:`mbn.controllers.kinds`) on a task:
    ``fitness(population)`` maps genes ``(P, size)`` to the task's fitness ``(P,)`` (summed over
    its episodes, as :func:`crossroad_fitness`), each genome run as the spec
    :meth:`spec` makes of it. Made by :func:`kind_fitness`; DE takes it as any fitness
    (:func:`start`, :func:`generation`, :meth:`StageContext.evolve
    <mbn.experiments.pipeline.context.StageContext.evolve>`).

    A population runs as one batched rollout: every genome's spec is made ready to run by its
    kind's runner, and their initial states are joined (the parts the genomes change, shared by
    each one's robots, get a batch axis: :func:`mbn.world.rollout.concatenate_states`), so the
    runner's controller must be the same object for every genome (its settings are the
    template's). Slower than the compiled fitnesses of ``mbn``'s own stages (the specs are made
    on the host each generation), and general.

    Attributes:
        template: the spec whose genes evolve (its settings, dt and sensors kept).
        task: a :class:`~mbn.experiments.crossroads.CrossroadTask` or a
            :class:`~mbn.experiments.maze_task.MazeTask`, of the template's ``dt`` and sensors.
        arrays: the task's arrays (made once).
        size: genes per genome (the length of the kind's ``genes`` of the template).
    """

    template: Any
    task: Task
    arrays: TaskArrays
    size: int

    def spec(self, genes: Any) -> Any:
        """The spec of one genome (the template with ``genes``, by its kind)."""
        from mbn.controllers import kind_of

        kind = kind_of(self.template)
        assert kind is not None  # checked by kind_fitness
        return kind.with_genes(self.template, np.asarray(genes))

    def __call__(self, population: Array) -> Array:
        from mbn.controllers import make_controller

        genes = np.asarray(population)
        if genes.ndim != 2 or genes.shape[1] != self.size:
            raise MbnInputError(f"a population of genomes of {self.size} genes, got {genes.shape}")
        task, arrays = self.task, self.arrays
        loaded = [
            make_controller(self.spec(g), where="genome", check_stability=False, noise=task.noise)
            for g in genes
        ]
        control = loaded[0].controller
        if any(each.controller is not control for each in loaded):
            raise MbnInputError(
                f"controller kind {loaded[0].kind}: its runner made a different controller for "
                "two genomes: the genes may change only what its state holds (its settings stay "
                "the template's, and the same settings give the same controller object)"
            )
        p, e = genes.shape[0], arrays.episodes
        dtype = jnp.asarray(genes).dtype
        state = concatenate_states([each.initial_state(e) for each in loaded], [e] * p)
        camera = loaded[0].camera
        config = task.rollout_config(**({"camera": camera} if camera is not None else {}))
        stats = run_rollout(
            arrays.world,
            control,
            state,
            put(np.tile(np.asarray(arrays.poses), (p, 1)), dtype),
            put(np.tile(np.asarray(arrays.maze_index), p), np.int32),
            config,
            junctions=arrays.junctions,
            key=task.rollout_key,
        ).stats
        per_episode = tile_fitness(arrays)(stats, task)
        return jnp.asarray(per_episode).reshape(p, e).sum(-1)


def kind_fitness(template: Any, task: Task, arrays: TaskArrays | None = None) -> KindFitness:
    """The fitness on ``task`` of genomes of ``template``'s kind (:class:`KindFitness`): a
    controller kind that defines genes (:meth:`ControllerKind.genes
    <mbn.controllers.kinds.ControllerKind.genes>` and ``with_genes``) is evolved with
    ``mbn``'s DE as it is. The template must run at the task's ``dt`` with the task's sensors
    (the sonars are cast as far as its normalised inputs read, :meth:`CrossroadTask.rollout_config
    <mbn.experiments.crossroads.CrossroadTask.rollout_config>`)."""
    from mbn.controllers import kind_of, make_controller

    kind = kind_of(template)
    if kind is None:
        raise MbnInputError(
            f"not a controller spec of a registered kind: {type(template).__name__}"
        )
    size = int(np.asarray(kind.genes(template)).shape[0])
    loaded = make_controller(template, where="template", check_stability=False)
    if loaded.dt != task.dt:
        raise MbnInputError(
            f"template: its robot step dt {loaded.dt:g} s is not the task's {task.dt:g} s"
        )
    if loaded.sensors != task.sensors:
        raise MbnInputError(
            f"template: its sensors {loaded.sensors} are not the task's {task.sensors}"
        )
    return KindFitness(template, task, arrays or task.arrays(), size)
