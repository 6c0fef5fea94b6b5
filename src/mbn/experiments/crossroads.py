"""The paper's training task: a robot in each of the seven crossroads, scored by a fitness.

Paper (section 3.1): "There are 7 kinds of crossroads ... Each robot is placed at the beginning
of each crossroad and is free to evolve for about 20 seconds. The final evaluation ... is the sum
of the evaluations obtained in each of the seven distinct simulations", with F_M (eq. 4) and F_R
or F_L (eq. 5).

Two fitnesses are available:

``"paper"``
    F_M + F_R (or F_L) per episode, exactly as published: F_M = V (1 - V_A) S_min with V the
    mean linear speed over the maximum, V_A the mean |angular speed| over the maximum and S_min
    the shortest sonar distance over 2 m (all in [0, 1]); F_R = S1 + S2 - S9 - S10 and
    F_L = S9 + S10 - S1 - S2 with S the mean proximity of the side sonars over the episode. It can
    be maximised by parking against the followed wall (a study here found exactly that).
``"branch"`` (default)
    progress into the arm the rule takes, times (1 - stall fraction), minus the stall fraction,
    plus 0.1 F_M for smooth, fast, clear motion. Progress is the distance of the final position
    beyond the junction along the correct arm, over the arm's length, in [0, 1] (0 anywhere
    else). It rewards exactly what the tests judge: the rule's branch, without stalling.

Both keep the paper's terms visible (:func:`paper_terms`). **A fitness of your own** is registered
by name (:func:`register_fitness`): a function of the episodes' statistics, the task's arrays
and the task, as the two above; a task names it by ``fitness``, and a rule may take it as its
own (``rules=``: the crossroad tasks of those rules use it unless they name another), which is
how a stage that builds its tasks by rule (``programs``) trains a new rule with it::

    register_fitness("u-turn-home", my_fitness, rules=("u-turn",))

A rule that turns back (:func:`mbn.world.rules.register_rule`) has the arm it came by, the south
one, as its arm (``"B"``).

Episodes: every crossroad from its start mark, and ``variants - 1`` more starts per crossroad
jittered (lateral, along the corridor, heading) with a seeded NumPy generator at this edge, so
that the evolved controller does not depend on one exact start.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import jax.numpy as jnp
import numpy as np
from jax import Array

from mbn.errors import MbnInputError
from mbn.experiments.fitness_registry import add_fitness
from mbn.experiments.starts import JITTER, jittered_starts
from mbn.world.engine import World, compile_mazes
from mbn.world.mazes.builtin import CROSSROAD_KINDS, check_approaches, crossroad
from mbn.world.mazes.model import Maze
from mbn.world.robot import MAX_ANGULAR_SPEED, MAX_LINEAR_SPEED
from mbn.world.rollout import EpisodeStats, RolloutConfig, input_reach, junction_arrays
from mbn.world.rules import parse_rule
from mbn.world.sensors import NoiseConfig, SensorConfig

__all__ = [
    "ARM_VECTORS",
    "EPISODE_FITNESS_MAX",
    "EPISODE_SECONDS",
    "FITNESSES",
    "F_M_WEIGHT",
    "RULES",
    "CrossroadTask",
    "TaskArrays",
    "episode_fitness",
    "paper_terms",
    "register_fitness",
    "rule_arm",
    "rule_fitness",
]

#: The paper's two rules (the wall followers); any rule of :mod:`mbn.world.rules` is trainable.
RULES: tuple[str, ...] = ("right", "left")
#: Length of a training episode (s); the paper says "about 20 seconds" (section 3.1), 30 s give
#: the robot time to reach the arm from a jittered start (docs/experiments.md).
EPISODE_SECONDS = 30.0
#: Weight of the paper's F_M in the branch fitness.
F_M_WEIGHT = 0.1
#: The largest branch fitness of one episode: full progress, no stall, F_M = 1.
EPISODE_FITNESS_MAX = 1.0 + F_M_WEIGHT
#: mbn's fitnesses (registered below, as a fitness of your own is: :func:`register_fitness`).
FITNESSES: tuple[str, ...] = ("branch", "paper")
#: The unit vector of each arm of a crossroad entered from the south (``"B"``: back, the south
#: arm itself, for a rule that turns back).
ARM_VECTORS = {"L": (-1.0, 0.0), "S": (0.0, 1.0), "R": (1.0, 0.0), "B": (0.0, -1.0)}
_ARM_OF = {"left": "L", "straight": "S", "right": "R", "back": "B"}
#: A crossroad fitness: per-episode values ``(..., E)`` from the episodes' statistics, the task's
#: arrays and the task.
Fitness = Callable[["EpisodeStats", "TaskArrays", "CrossroadTask"], Array]
#: The fitnesses by name (:func:`register_fitness`), and the fitness of a rule that has one.
_FITNESSES: dict[str, Fitness] = {}
_RULE_FITNESS: dict[str, str] = {}


def register_fitness(name: str, fitness: Fitness, *, rules: Sequence[str] = ()) -> None:
    """Register a crossroad fitness under ``name`` (lower-case words joined by ``-``):
    ``fitness(stats, arrays, task)`` gives every episode's value (``(..., E)``, a JAX function:
    it runs inside the compiled fitness; :func:`episode_fitness` calls it). A task takes it by
    ``fitness=name``; ``rules``: rules (:mod:`mbn.world.rules`) whose tasks take it when they
    name no fitness (:func:`rule_fitness`). A name or a rule's fitness registered already is
    refused in one line (the same function again is allowed: a module imported twice)."""
    add_fitness(_FITNESSES, _RULE_FITNESS, name, fitness, rules, "stats, arrays, task")


def rule_fitness(rule: str) -> str:
    """The fitness a crossroad task of ``rule`` takes when it names none: the one registered
    for the rule (:func:`register_fitness`), else ``"branch"``."""
    return _RULE_FITNESS.get(parse_rule(rule).name, "branch")


def rule_arm(kind: str, rule: str) -> str:
    """The exit (``"L"``, ``"S"``, ``"R"``, or ``"B"`` back) a rule (:mod:`mbn.world.rules`) takes
    at a crossroad kind entered from the south: for a priority order the first of its order
    that the kind has (the right-hand rule first of R, S, L; the left-hand rule first of L, S,
    R)."""
    parsed = parse_rule(rule)
    if kind not in CROSSROAD_KINDS:
        raise MbnInputError(
            f"unknown crossroad kind {kind!r} (known: {', '.join(CROSSROAD_KINDS)})"
        )
    opened = {e for e, arm in _ARM_OF.items() if arm in kind}
    return _ARM_OF[parsed.exit(opened)]


@dataclass(frozen=True)
class CrossroadTask:
    """The crossroad training task.

    Attributes:
        rule: the rule rewarded (:mod:`mbn.world.rules`: "right", "left", "straight-right", ...
            or an order such as "SRL"; kept as its name).
        fitness: "branch" or "paper" (see the module docstring), or a registered one
            (:func:`register_fitness`); left empty, the rule's (:func:`rule_fitness`: "branch"
            unless one was registered for the rule).
        variants: starts per crossroad: the start mark and ``variants - 1`` jittered ones.
        seconds: episode length (the paper: "about 20 seconds"; default 30 s, see docs).
        dt: robot step (s).
        jitter: lateral (m), along (m), heading (degrees) half-ranges of the jittered starts.
        seed: seed of the jittered starts (recorded in results).
        sensors: sonar settings (normalisation of S).
        tile: put a tile of this many colours in every crossroad's south arm (PM training).
        approaches: how the robot enters each crossroad's south arm: ``"south"`` (the paper's:
            it starts in the arm) and/or ``"west"``/``"east"`` (it starts in a corridor and
            turns a corner into the arm, as in a maze; :func:`mbn.world.mazes.builtin.crossroad`).
            Every approach gets the seven kinds.
        noise: sensor, actuator and neuron noise of the episodes (off by default;
            ``docs/noise.md``), drawn from ``noise_key``, the same key at every evaluation: a
            genome's trial and the member it may replace, which DE evaluates in the same slot
            of the population, meet the same noise (common random numbers), so the fitness
            stays deterministic and the greedy replacement fair.
        noise_key: the PRNG key of the noise (required when noise is on).
    """

    rule: str = "right"
    fitness: str = ""
    variants: int = 6
    seconds: float = EPISODE_SECONDS
    dt: float = 0.1
    jitter: tuple[float, float, float] = JITTER
    seed: int = 0
    sensors: SensorConfig = field(default_factory=SensorConfig)
    tile: int | None = None
    approaches: tuple[str, ...] = ("south",)
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    noise_key: Array | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "rule", parse_rule(self.rule).name)
        if self.noise.enabled and self.noise_key is None:
            raise MbnInputError("a crossroad task with noise needs a noise_key")
        if not self.fitness:
            object.__setattr__(self, "fitness", rule_fitness(self.rule))
        if self.fitness not in _FITNESSES:
            raise MbnInputError(
                f"fitness must be one of {', '.join(_FITNESSES)}, got {self.fitness!r}"
            )
        if not (isinstance(self.variants, int) and self.variants >= 1):
            raise MbnInputError(f"variants must be an integer >= 1, got {self.variants!r}")
        if not (self.seconds > 0 and self.dt > 0):
            raise MbnInputError("seconds and dt must be > 0")
        if any(j < 0 for j in self.jitter):
            raise MbnInputError(f"jitter must be >= 0, got {self.jitter!r}")
        check_approaches(self.approaches)

    @property
    def steps(self) -> int:
        return max(1, round(self.seconds / self.dt))

    def rollout_config(self, **kw: Any) -> RolloutConfig:
        """The task's rollout settings; the sonars are cast only as far as its inputs and its
        fitness read them (:func:`mbn.world.rollout.input_reach`) unless ``kw`` says."""
        kw.setdefault("sonar_reach", input_reach(self.sensors, self.noise))
        return RolloutConfig(
            steps=self.steps, dt=self.dt, sensors=self.sensors, noise=self.noise, **kw
        )

    @property
    def rollout_key(self) -> Array | None:
        """The key a rollout of this task draws its noise from (None without noise)."""
        return self.noise_key if self.noise.enabled else None

    def arrays(self) -> TaskArrays:
        """Mazes, compiled world and per-episode arrays (NumPy at this edge, once)."""
        pairs = [(a, k) for a in self.approaches for k in CROSSROAD_KINDS]
        mazes = [crossroad(k, tile=self.tile, approach=a) for a, k in pairs]
        world = compile_mazes(mazes)
        base = np.stack([m.starts[0] for m in mazes])
        poses = jittered_starts(base, self.variants, self.jitter, self.seed)
        maze_index = np.tile(np.arange(len(mazes)), self.variants)
        target = np.array([ARM_VECTORS[rule_arm(k, self.rule)] for _, k in pairs])
        centre = np.array([[m.bounds[1] / 2, m.bounds[3] / 2] for m in mazes])
        return TaskArrays(
            mazes=mazes,
            world=world,
            junctions=junction_arrays(mazes, world),
            poses=poses,
            maze_index=maze_index,
            target=target[maze_index],
            centre=centre[maze_index],
            cell=float(mazes[0].cell or 1.2),
            arm_length=3 * float(mazes[0].cell or 1.2),
        )


@dataclass(frozen=True)
class TaskArrays:
    """A task's mazes and per-episode arrays: start ``poses (E, 3)``, ``maze_index (E,)``, the
    unit vector of the rule's arm ``target (E, 2)`` and the junction centre ``centre (E, 2)``
    (NumPy at the edge; device arrays, or traced ones, inside a compiled fitness)."""

    mazes: list[Maze]
    world: World
    junctions: Array
    poses: np.ndarray | Array
    maze_index: np.ndarray | Array
    target: np.ndarray | Array
    centre: np.ndarray | Array
    cell: float
    arm_length: float

    @property
    def episodes(self) -> int:
        return len(self.poses)


def paper_terms(stats: EpisodeStats, far: float = 2.0) -> dict[str, Array]:
    """The paper's fitness terms per episode: F_M (eq. 4) and F_R, F_L (eq. 5).

    ``stats`` must come from a rollout with the paper's 10 sonars (``S_mean`` over s1..s10, as
    proximity); ``far`` is the distance that maps S_min into [0, 1].
    """
    V = jnp.clip(stats.mean_v / MAX_LINEAR_SPEED, 0.0, 1.0)
    VA = jnp.clip(stats.mean_abs_w / MAX_ANGULAR_SPEED, 0.0, 1.0)
    s_min = jnp.clip(stats.min_range / far, 0.0, 1.0)
    S = stats.S_mean
    right = S[..., 0] + S[..., 1]
    left = S[..., 8] + S[..., 9]
    return {"F_M": V * (1.0 - VA) * s_min, "F_R": right - left, "F_L": left - right}


def branch_progress(stats: EpisodeStats, arrays: TaskArrays) -> Array:
    """How far (0..1) the final position lies inside the arm the rule takes."""
    rel = stats.final_pose[..., :2] - jnp.asarray(arrays.centre)
    t = jnp.asarray(arrays.target)
    half = arrays.cell / 2
    along = jnp.sum(rel * t, -1) - half
    lateral = jnp.abs(rel[..., 0] * t[..., 1] - rel[..., 1] * t[..., 0])
    return jnp.where(lateral <= half, jnp.clip(along / arrays.arm_length, 0.0, 1.0), 0.0)


def episode_fitness(stats: EpisodeStats, arrays: TaskArrays, task: CrossroadTask) -> Array:
    """Fitness of every episode ``(..., E)``, by the task's fitness (:func:`register_fitness`);
    sum over episodes for a controller's fitness."""
    return _FITNESSES[task.fitness](stats, arrays, task)


def paper_fitness(stats: EpisodeStats, arrays: TaskArrays, task: CrossroadTask) -> Array:
    """The paper's fitness ``"paper"``: F_M + F_R (F_L for any rule but right)."""
    terms = paper_terms(stats, task.sensors.far)
    return terms["F_M"] + (terms["F_R"] if task.rule == "right" else terms["F_L"])


def branch_fitness(stats: EpisodeStats, arrays: TaskArrays, task: CrossroadTask) -> Array:
    """The fitness ``"branch"`` (the default): progress into the rule's arm times (1 - stall),
    minus the stall fraction, plus 0.1 F_M."""
    terms = paper_terms(stats, task.sensors.far)
    stall = stats.stall_fraction
    return branch_progress(stats, arrays) * (1.0 - stall) - stall + F_M_WEIGHT * terms["F_M"]


register_fitness("branch", branch_fitness)
register_fitness("paper", paper_fitness)
