"""Selection across a maze family: training episodes drawn from its train split
(``docs/generalization.md``, "Selection across the family").

A :class:`MazeTask` is a training task like :class:`mbn.experiments.crossroads.CrossroadTask`,
with episodes in generated mazes instead of the seven crossroads: a **pool** of ``pool`` mazes
of the family, drawn once from the train split by ``seed`` (compiled into one world, so that
every draw runs in the same compiled program), and for **draw** ``k`` the episodes: ``mazes``
mazes of the pool and ``starts`` of each one's start marks, jittered (a NumPy generator seeded
by ``(seed, k)``, at this edge). Evolution redraws the episodes every N generations by taking
the task of the next draw (:meth:`MazeTask.redrawn`); the test and validation splits are never
drawn from (:func:`mbn.world.mazes.families.check_use`).

The fitness of an episode (``"junctions"``) rewards what the tests judge:

    progress * (1 - stall) - w stall + 0.1 F_M

``progress`` is the share of the first ``junctions`` junction passes taken by the rule in force
before the first wrong one (0 .. 1: every pass right until the last judged one is 1), ``stall``
the stall fraction until the last judged junction was left (over the whole episode if it never
was), ``w`` the weight of stalling (``stall_weight``: 1, as in the crossroads' branch fitness),
and ``F_M`` the paper's motion term (eq. 4), weighted as there. The rule in force is ``rule``;
for ``"tiles"`` the rule of the last tile driven over (``tile_rules``), ``initial`` before the
first. It judges any rule, a registered one (:func:`mbn.world.rules.register_rule`) too.

**A fitness of your own** is registered by name (:func:`register_fitness`), as a crossroad one
is (:func:`mbn.experiments.crossroads.register_fitness`): ``fitness(stats, task)``, every
episode's value; a task names it by ``fitness``, or takes it as its rule's (``rules=``).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import jax.numpy as jnp
import numpy as np
from jax import Array

from mbn.errors import MbnInputError
from mbn.experiments.crossroads import F_M_WEIGHT, TaskArrays, paper_terms
from mbn.experiments.fitness_registry import add_fitness
from mbn.experiments.starts import JITTER, jittered_starts
from mbn.world.engine import compile_mazes
from mbn.world.mazes import families
from mbn.world.mazes.model import Maze
from mbn.world.rollout import EpisodeStats, RolloutConfig, input_reach, junction_arrays
from mbn.world.rules import parse_rule, rule_exit_codes
from mbn.world.sensors import NoiseConfig, SensorConfig

__all__ = [
    "MAZE_FITNESSES",
    "MazeTask",
    "junction_progress",
    "maze_episode_fitness",
    "register_fitness",
    "rule_fitness",
]

#: mbn's fitnesses of a maze task (registered below, as one of your own is:
#: :func:`register_fitness`).
MAZE_FITNESSES = ("junctions",)
#: A maze task's fitness: per-episode values from the episodes' statistics and the task.
MazeFitness = Callable[[EpisodeStats, "MazeTask"], Array]
_FITNESSES: dict[str, MazeFitness] = {}
_RULE_FITNESS: dict[str, str] = {}


def register_fitness(name: str, fitness: MazeFitness, *, rules: Sequence[str] = ()) -> None:
    """Register a maze task's fitness under ``name`` (lower-case words joined by ``-``):
    ``fitness(stats, task)`` gives every episode's value (a JAX function, run inside the
    compiled fitness). A task takes it by ``fitness=name``; ``rules``: rules whose maze tasks
    take it when they name no fitness (:func:`rule_fitness`). A name or a rule's fitness
    registered already is refused in one line (the same function again is allowed)."""
    add_fitness(_FITNESSES, _RULE_FITNESS, name, fitness, rules, "stats, task")


def rule_fitness(rule: str) -> str:
    """The fitness a maze task of ``rule`` takes when it names none: the one registered for the
    rule (:func:`register_fitness`), else ``"junctions"`` (for ``"tiles"`` too)."""
    if rule == "tiles":
        return _RULE_FITNESS.get("tiles", "junctions")
    return _RULE_FITNESS.get(parse_rule(rule).name, "junctions")


@dataclass(frozen=True)
class MazeTask:
    """Training episodes in mazes of a family (see the module docstring).

    Attributes:
        rule: the rule rewarded (a rule of :mod:`mbn.world.rules`), or "tiles".
        family: the maze family (:data:`mbn.world.mazes.families.FAMILIES`).
        pool: training mazes drawn from the train split (once, by ``seed``).
        mazes: mazes of the pool in one draw.
        starts: start marks of each maze in one draw (each jittered).
        junctions: junction passes judged per episode.
        fitness: "junctions" or a registered one (:func:`register_fitness`); left empty, the
            rule's (:func:`rule_fitness`: "junctions" unless one was registered for it).
        seconds: episode length (s).
        dt: robot step (s).
        jitter: lateral (m), along (m), heading (degrees) half-ranges of the starts.
        seed: seed of the pool and of the draws (recorded in results).
        draw: which draw of episodes (0, 1, ...: evolution redraws by taking the next).
        initial: for "tiles", the rule before the first tile.
        tile_rules: for "tiles", the rule each tile kind puts in force.
        stall_weight: the weight of the stall fraction subtracted (1: as the crossroads'
            branch fitness).
        sensors: sonar settings.
        noise: sensor, actuator and neuron noise (off by default), drawn from ``noise_key``.
        noise_key: the PRNG key of the noise (required when noise is on).
    """

    rule: str = "right"
    family: str = "grid"
    pool: int = 256
    mazes: int = 8
    starts: int = 4
    junctions: int = 3
    fitness: str = ""
    seconds: float = 40.0
    dt: float = 0.1
    jitter: tuple[float, float, float] = JITTER
    seed: int = 0
    draw: int = 0
    initial: str = "right"
    tile_rules: tuple[str, ...] = ("right", "left")
    stall_weight: float = 1.0
    sensors: SensorConfig = field(default_factory=SensorConfig)
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    noise_key: Array | None = None

    def __post_init__(self) -> None:
        if self.rule != "tiles":
            object.__setattr__(self, "rule", parse_rule(self.rule).name)
        object.__setattr__(self, "initial", parse_rule(self.initial).name)
        object.__setattr__(self, "tile_rules", tuple(parse_rule(r).name for r in self.tile_rules))
        fam = families.family(self.family)
        if self.rule == "tiles" and not fam.tile_kinds:
            raise MbnInputError(f"rule 'tiles' needs a family with tiles, got {self.family!r}")
        if not self.fitness:
            object.__setattr__(self, "fitness", rule_fitness(self.rule))
        if self.fitness not in _FITNESSES:
            raise MbnInputError(
                f"fitness must be one of {', '.join(_FITNESSES)}, got {self.fitness!r}"
            )
        for name in ("pool", "mazes", "starts", "junctions"):
            value = getattr(self, name)
            if not (isinstance(value, int) and not isinstance(value, bool) and value >= 1):
                raise MbnInputError(f"{name} must be an integer >= 1, got {value!r}")
        if self.mazes > self.pool:
            raise MbnInputError(f"mazes ({self.mazes}) must be at most pool ({self.pool})")
        if self.starts > fam.starts:
            raise MbnInputError(
                f"starts ({self.starts}) must be at most the family's start marks ({fam.starts})"
            )
        if not (isinstance(self.draw, int) and self.draw >= 0):
            raise MbnInputError(f"draw must be an integer >= 0, got {self.draw!r}")
        if not (self.seconds > 0 and self.dt > 0):
            raise MbnInputError("seconds and dt must be > 0")
        if self.noise.enabled and self.noise_key is None:
            raise MbnInputError("a maze task with noise needs a noise_key")

    @property
    def steps(self) -> int:
        return max(1, round(self.seconds / self.dt))

    @property
    def episodes(self) -> int:
        return self.mazes * self.starts

    def rollout_config(self, **kw: Any) -> RolloutConfig:
        """The task's rollout settings (junction passes kept: at least ``junctions``)."""
        kw.setdefault("sonar_reach", input_reach(self.sensors, self.noise))
        kw.setdefault("max_junctions", max(8, self.junctions))
        return RolloutConfig(
            steps=self.steps, dt=self.dt, sensors=self.sensors, noise=self.noise, **kw
        )

    @property
    def rollout_key(self) -> Array | None:
        return self.noise_key if self.noise.enabled else None

    def redrawn(self, draw: int) -> MazeTask:
        """The same task with the episodes of draw ``draw``."""
        from dataclasses import replace

        return replace(self, draw=int(draw))

    def pool_seeds(self) -> list[int]:
        """The train-split seeds of the pool (drawn by ``seed``; checked: train only)."""
        return list(_pool_seeds(self.family, self.pool, self.seed))

    def arrays(self) -> TaskArrays:
        """The pool's world and this draw's episodes (``target`` and ``centre`` unused: zeros)."""
        mazes, world, junctions = _pool(self.family, self.pool, self.seed)
        rng = np.random.default_rng([self.seed, self.draw, 47])
        chosen = rng.choice(self.pool, self.mazes, replace=False)
        poses, index = [], []
        for m in chosen:
            marks = rng.choice(len(mazes[m].starts), self.starts, replace=False)
            poses.append(mazes[m].starts[np.sort(marks)])
            index.append(np.full(self.starts, m, np.int32))
        base = np.concatenate(poses)
        jitter_seed = int(rng.integers(2**31))
        # every start jittered (one variant of each, none from the mark exactly)
        jittered = jittered_starts(base, 2, self.jitter, jitter_seed)[len(base) :]
        e = len(base)
        return TaskArrays(
            mazes=list(mazes),
            world=world,
            junctions=junctions,
            poses=jittered,
            maze_index=np.concatenate(index),
            target=np.zeros((e, 2)),
            centre=np.zeros((e, 2)),
            cell=float(mazes[0].cell or 1.2),
            arm_length=0.0,
        )


@functools.lru_cache(maxsize=8)
def _pool_seeds(family: str, pool: int, seed: int) -> tuple[int, ...]:
    rng = np.random.default_rng([seed, 4747])
    train = families.family_splits(family)["train"]
    seeds = sorted(int(s) for s in rng.choice(len(train), pool, replace=False) + train[0])
    families.check_use(seeds, "train", where=f"maze task pool of {family}", fam=family)
    return tuple(seeds)


@functools.lru_cache(maxsize=4)
def _pool(family: str, pool: int, seed: int) -> tuple[tuple[Maze, ...], Any, Array]:
    """The pool's mazes, compiled world and junction tables (once per process)."""
    mazes = tuple(families.generate(family, s) for s in _pool_seeds(family, pool, seed))
    world = compile_mazes(list(mazes))
    return mazes, world, junction_arrays(list(mazes), world)


def junction_progress(stats: EpisodeStats, task: MazeTask) -> tuple[Array, Array]:
    """``(progress, stall)`` of every episode: the share of the first ``junctions`` passes taken
    by the rule in force before the first wrong one, and the stall fraction until the last
    judged junction was left (the whole episode's when it never was)."""
    J = task.junctions
    exits = stats.junction_exit[..., :J]
    opened = stats.junction_open[..., :J]
    n = jnp.minimum(stats.n_junctions, stats.junction_exit.shape[-1])
    if task.rule == "tiles":
        tile = stats.junction_tile[..., :J]
        rule = rule_exit_codes(task.initial, opened)
        for colors, name in enumerate(task.tile_rules, start=1):
            rule = jnp.where(tile == colors, rule_exit_codes(name, opened), rule)
    else:
        rule = rule_exit_codes(task.rule, opened)
    passed = jnp.arange(J) < n[..., None]
    right = passed & (exits == rule)
    prefix = jnp.cumprod(right.astype(jnp.int32), axis=-1).sum(-1)
    progress = prefix / J
    done = n >= J
    out_step = stats.junction_exit_step[..., J - 1]
    stalls = stats.junction_stalls[..., J - 1]
    stall = jnp.where(done, stalls / jnp.maximum(out_step, 1), stats.stall_fraction)
    return progress, stall


def maze_episode_fitness(stats: EpisodeStats, task: MazeTask) -> Array:
    """Fitness of every episode, by the task's fitness (:func:`register_fitness`)."""
    return _FITNESSES[task.fitness](stats, task)


def junctions_fitness(stats: EpisodeStats, task: MazeTask) -> Array:
    """The fitness ``"junctions"`` (see the module docstring)."""
    progress, stall = junction_progress(stats, task)
    f_m = paper_terms(stats, task.sensors.far)["F_M"]
    return progress * (1.0 - stall) - task.stall_weight * stall + F_M_WEIGHT * f_m


register_fitness("junctions", junctions_fitness)
