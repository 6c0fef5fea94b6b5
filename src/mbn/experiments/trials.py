"""The paper's test protocol: start marks of a maze, J consecutive junctions, little stalling.

Paper (section 3.1): "The networks obtained were tested placing the robot in 10 different
positions in the maze and observing the robot behavior while driving through three consecutive
crossroads. The positions were chosen in such a way that the robot starts its test in the middle
of a corridor and oriented with its lateral part parallel to the wall."

A trial here: the robot starts at a start mark (exactly, or jittered: lateral +-0.15 m, along the
corridor +-0.3 m, heading +-10 degrees) and runs up to a time limit. It **succeeds** when its
first J junction passes (decision cells: T and plus crossings and L turns) each take the exit of
the rule in force, and it was stalled in at most 2 % of its steps until it left the J-th junction.
The rule in force is fixed ("right", "left"), or, for "tiles", the rule of the last tile the
robot drove over when it entered the junction (one colour: right, two colours: left; before the
first tile: ``initial``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import jax
import numpy as np
from jax import Array

from mbn.errors import MbnInputError
from mbn.experiments.starts import JITTER, mark_starts
from mbn.host import put
from mbn.world.engine import CameraConfig, compile_mazes
from mbn.world.judged import run_rollout_until_judged
from mbn.world.junctions import rule_route
from mbn.world.mazes.model import TILE_COLORS, Maze
from mbn.world.rollout import (
    EpisodeStats,
    RolloutConfig,
    RolloutResult,
    concatenate_states,
    input_reach,
    junction_arrays,
    run_rollout,
)
from mbn.world.rules import NAMED_RULES, parse_rule, rule_exit_codes, rule_names
from mbn.world.sensors import NoiseConfig, SensorConfig

__all__ = [
    "BEHAVIORS",
    "MAX_STALL_FRACTION",
    "MIN_SECONDS",
    "ROUTE_MARGIN",
    "TYPICAL_SPEED",
    "TrialGroup",
    "TrialSpec",
    "agreement",
    "as_test_record",
    "join_verdicts",
    "judge",
    "longest_route",
    "rate_record",
    "route_seconds",
    "run_loaded_trials",
    "run_trial_groups",
    "run_trials",
    "summary",
    "trial_starts",
    "verdict_details",
]

#: The behaviours named on the command line: the rules with names, and the MBN's tiles.
BEHAVIORS: tuple[str, ...] = (*NAMED_RULES, "tiles")
#: A trial fails when the robot was stalled in more than this fraction of its steps.
MAX_STALL_FRACTION = 0.02
#: The speed the evolved wall followers typically drive at (m/s; 60 % of v_max: speed is a small
#: term of their fitness, docs/reproduce.md "Time limits").
TYPICAL_SPEED = 0.3
#: A derived time limit is this many times the longest route's time at :data:`TYPICAL_SPEED`.
ROUTE_MARGIN = 1.5
#: A derived time limit is never below this (s): the former fixed default of ``mbn evaluate``.
MIN_SECONDS = 60.0


@dataclass(frozen=True)
class TrialSpec:
    """How a controller is tested in a maze.

    Attributes:
        behavior: a rule (:mod:`mbn.world.rules`: "right", "left", "straight-right", ... or an
            order such as "SRL"; kept as its name) or "tiles" (the rule of the last tile driven
            over).
        initial: the rule before the first tile ("tiles" only): a rule ("right", "left", ...)
            or "none" —
            junctions passed before the first tile are then not judged (the J judged junctions
            are the first J after it).
        repeats: trials per start mark: the first from the mark exactly, the others jittered.
        junctions: consecutive junctions judged (the paper: 3).
        seconds: time limit of a trial.
        jitter: lateral (m), along (m), heading (degrees) half-ranges.
        seed: seed of the jitter (NumPy, at this edge).
        exact_first: whether the first trial of each mark starts from the mark exactly (else
            all ``repeats`` trials of a mark are jittered).
        tile_rules: "tiles" only: the rule a tile of 1, 2, ... colours puts in force (the
            paper's: one colour right, two colours left); a maze with a tile of more colours
            than rules is refused (:meth:`check_maze`).
    """

    behavior: str = "right"
    initial: str = "right"
    repeats: int = 1
    junctions: int = 3
    seconds: float = 60.0
    jitter: tuple[float, float, float] = JITTER
    seed: int = 0
    exact_first: bool = True
    tile_rules: tuple[str, ...] = ("right", "left")

    def __post_init__(self) -> None:
        if self.behavior != "tiles":
            try:
                rule = parse_rule(self.behavior)
            except MbnInputError:
                raise MbnInputError(
                    f"behavior must be a rule ({', '.join(rule_names())}, or an order such as "
                    f"'SRL') or tiles, got {self.behavior!r}"
                ) from None
            object.__setattr__(self, "behavior", rule.name)
        if not 1 <= len(self.tile_rules) <= len(TILE_COLORS):
            raise MbnInputError(
                f"tile_rules: one rule per tile kind (1 to {len(TILE_COLORS)}), got "
                f"{self.tile_rules!r}"
            )
        object.__setattr__(self, "tile_rules", tuple(parse_rule(r).name for r in self.tile_rules))
        if self.initial != "none":
            try:
                object.__setattr__(self, "initial", parse_rule(self.initial).name)
            except MbnInputError as exc:
                raise MbnInputError(f"initial: {exc} (or none)") from None
        if not (isinstance(self.repeats, int) and self.repeats >= 1):
            raise MbnInputError(f"repeats must be an integer >= 1, got {self.repeats!r}")
        if not (isinstance(self.junctions, int) and 1 <= self.junctions <= 32):
            raise MbnInputError(f"junctions must be an integer in 1..32, got {self.junctions!r}")
        if not (self.seconds > 0 and math.isfinite(self.seconds)):
            raise MbnInputError(f"seconds must be > 0, got {self.seconds!r}")

    def check_maze(self, maze: Maze) -> None:
        """Refuse a maze the spec cannot be run in (one clear line)."""
        if len(maze.starts) == 0:
            raise MbnInputError(f"maze {maze.name!r} has no start marks")
        if maze.grid is None:
            raise MbnInputError(
                f"maze {maze.name!r} is not a grid maze: the junction test needs one"
            )
        if self.behavior == "tiles" and not maze.tiles:
            raise MbnInputError(f"behavior 'tiles' needs tiles, and maze {maze.name!r} has none")
        if self.behavior == "tiles":
            most = max(t.colors for t in maze.tiles)
            if most > len(self.tile_rules):
                raise MbnInputError(
                    f"maze {maze.name!r} has {most}-colour tiles, and the rules in force are "
                    f"known for tiles of up to {len(self.tile_rules)} colours "
                    f"({', '.join(self.tile_rules)})"
                )


def trial_starts(maze: Maze, spec: TrialSpec) -> np.ndarray:
    """Start poses ``(marks * repeats, 3)`` of ``spec`` in ``maze``
    (:func:`mbn.experiments.starts.mark_starts`)."""
    return mark_starts(maze.starts, spec.repeats, spec.jitter, spec.seed, spec.exact_first)


def longest_route(maze: Maze, spec: TrialSpec) -> float | None:
    """The longest route (metres) from a start mark of ``maze`` until the ``spec.junctions``-th
    judged junction is left, for a robot that keeps the rule in force
    (:func:`mbn.world.junctions.rule_route`): ``spec.behavior``'s rule; for "tiles" the rule of
    the last tile entered, ``spec.initial`` before the first (with "none": the longer of right
    and left, counting junctions from the first tile). None when no walk gets there."""
    if spec.behavior == "tiles":
        initials = spec.tile_rules if spec.initial == "none" else (spec.initial,)
        walks = [(rule, True, spec.initial == "none") for rule in initials]
    else:
        walks = [(spec.behavior, False, False)]
    routes = [
        rule_route(
            maze,
            tuple(start),
            rule,
            spec.junctions,
            follow_tiles=follow,
            count_from_tile=from_tile,
            tile_rules=spec.tile_rules,
        )
        for start in np.asarray(maze.starts)
        for rule, follow, from_tile in walks
    ]
    found = [r for r in routes if r is not None]
    return max(found) if found else None


def route_seconds(maze: Maze, spec: TrialSpec) -> float:
    """A time limit for ``spec``'s trials in ``maze``: :data:`ROUTE_MARGIN` x the time of the
    :func:`longest_route` at :data:`TYPICAL_SPEED`, rounded up to 10 s, and at least
    :data:`MIN_SECONDS` (also when no route gets there). ``fig4``: 17.4 m, 90 s, the limit
    ``mbn reproduce`` tests its networks with."""
    route = longest_route(maze, spec)
    if route is None:
        return MIN_SECONDS
    return max(MIN_SECONDS, 10.0 * math.ceil(ROUTE_MARGIN * route / TYPICAL_SPEED / 10.0 - 1e-9))


def judge(stats: EpisodeStats, spec: TrialSpec) -> dict[str, np.ndarray]:
    """Judge every episode: per trial ``success``, ``correct`` junctions among the first J,
    ``judged`` junctions (J or fewer if the robot passed fewer), ``stall`` fraction until the J-th
    junction was left (or over the whole trial if it never was), ``timed_out`` (the trial ended
    before its J-th judged junction with no wrong exit and no stall failure: the time limit, not
    the controller, ended it), ``exits`` ``(n, J)``: the exit taken at each judged junction
    (-1 where there was none), ``open`` ``(n, J)``: its open exits (a
    :data:`~mbn.world.rules.OPEN_BITS` mask; -1 where there was none) and ``expected``
    ``(n, J)``: the exit the rule in force takes there, ``cells`` ``(n, J, 2)`` its grid cell
    (row, column) and ``headings`` ``(n, J)`` the compass direction the robot entered it by
    (0..3 = N, E, S, W) (-1 where there was none), ``stretch_steps`` and ``stretch_stalls``
    ``(n, J)``: the steps and the stalled moves from the previous pass's exit (or the start) to
    this pass's (-1 where there was none)."""
    J = spec.junctions
    kept = np.asarray(stats.junction_exit).shape[1]
    n = np.minimum(np.asarray(stats.n_junctions), kept)
    if kept < J:
        raise MbnInputError(
            f"the rollout kept {kept} junction passes per episode; {J} are judged "
            "(raise RolloutConfig.max_junctions)"
        )
    fields = {
        name: np.asarray(getattr(stats, f"junction_{name}"))
        for name in ("exit", "open", "tile", "exit_step", "stalls", "cell", "heading")
    }
    # each pass's stretch: the steps and stalled moves since the previous pass's exit (or the
    # start), taken before the passes are reordered below
    made = np.arange(kept)[None, :] < n[:, None]
    before = np.concatenate([np.zeros((len(n), 1), np.int64), fields["exit_step"][:, :-1]], 1)
    stalls_before = np.concatenate([np.zeros((len(n), 1), np.int64), fields["stalls"][:, :-1]], 1)
    fields["stretch_steps"] = np.where(made, fields["exit_step"] - before, -1)
    fields["stretch_stalls"] = np.where(made, fields["stalls"] - stalls_before, -1)
    if spec.behavior == "tiles" and spec.initial == "none":
        # drop the passes made before the first tile: move the others to the front, in order
        valid = (fields["tile"] > 0) & (np.arange(kept)[None, :] < n[:, None])
        order = np.argsort(~valid, axis=1, kind="stable")
        fields = {
            k: np.take_along_axis(v, order.reshape(order.shape + (1,) * (v.ndim - 2)), axis=1)
            for k, v in fields.items()
        }
        n = valid.sum(1)
    exits = fields["exit"][:, :J]
    opened = fields["open"][:, :J]
    if spec.behavior != "tiles":
        rule = rule_exit_codes(spec.behavior, opened)
    else:
        tile = fields["tile"][:, :J]
        # before the first tile: the initial rule ("none": those passes were dropped above)
        rule = rule_exit_codes(spec.initial if spec.initial != "none" else "right", opened)
        for colors, name in enumerate(spec.tile_rules, start=1):
            rule = np.where(tile == colors, rule_exit_codes(name, opened), rule)
    passed = np.arange(J)[None, :] < n[:, None]
    correct = passed & (exits == rule)
    judged = np.minimum(n, J)
    out_step = fields["exit_step"][:, J - 1]
    stalls = fields["stalls"][:, J - 1]
    whole = np.asarray(stats.stall_fraction)
    stall = np.where(n >= J, stalls / np.maximum(out_step, 1), whole)
    no_wrong_exit = correct.sum(1) == judged
    calm = stall <= MAX_STALL_FRACTION
    success = (n >= J) & no_wrong_exit & calm
    return {
        "success": success,
        "timed_out": (n < J) & no_wrong_exit & calm,
        "correct": correct.sum(1),
        "judged": judged,
        "stall": stall,
        "exits": np.where(passed, exits, -1),
        "open": np.where(passed, opened, -1),
        "expected": np.where(passed, rule, -1),
        "cells": np.where(passed[..., None], fields["cell"][:, :J], -1),
        "headings": np.where(passed, fields["heading"][:, :J], -1),
        "stretch_steps": np.where(passed, fields["stretch_steps"][:, :J], -1),
        "stretch_stalls": np.where(passed, fields["stretch_stalls"][:, :J], -1),
    }


def verdict_details(verdict: dict[str, np.ndarray]) -> dict[str, list[Any]]:
    """What a run records of each trial of a verdict, for its pictures: ``success``,
    ``correct``, ``judged``, ``stall`` (5 decimals) and ``timed_out``, as JSON lists."""
    return {
        "success": verdict["success"].astype(int).tolist(),
        "correct": verdict["correct"].astype(int).tolist(),
        "judged": verdict["judged"].astype(int).tolist(),
        "stall": np.round(verdict["stall"].astype(float), 5).tolist(),
        "timed_out": verdict["timed_out"].astype(int).tolist(),
    }


def join_verdicts(verdicts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Verdicts of the same kind of trials (e.g. in several mazes) as one, trials in order."""
    return {key: np.concatenate([np.asarray(v[key]) for v in verdicts]) for key in verdicts[0]}


def agreement(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> dict[str, Any]:
    """How often two controllers' verdicts on the same trials took the same exits at every
    judged junction: ``trials``, ``same_branches``, ``rate``."""
    same = np.all(np.asarray(a["exits"]) == np.asarray(b["exits"]), axis=1)
    return {"trials": int(same.size), "same_branches": int(same.sum()), "rate": float(same.mean())}


def rate_record(verdict: dict[str, np.ndarray]) -> dict[str, Any]:
    """``successes``, ``trials``, ``rate`` and ``wilson95`` (the Wilson 95 % interval) of
    judged trials: how the noise and ablation experiments record a test."""
    from mbn.stats import wilson_interval

    s = summary(verdict)
    lo, hi = wilson_interval(int(s["successes"]), int(s["trials"]))
    return {
        "successes": s["successes"],
        "trials": s["trials"],
        "rate": s["success_rate"],
        "wilson95": [lo, hi],
    }


def as_test_record(record: dict[str, Any]) -> dict[str, Any]:
    """A :func:`rate_record` as ``results.json`` keeps a test (``trials``, ``successes``,
    ``success_rate``): the form a sweep reads (``mbn.experiments.sweep.summary``)."""
    return {
        "trials": int(record["trials"]),
        "successes": int(record["successes"]),
        "success_rate": float(record["rate"]),
    }


def summary(verdict: dict[str, np.ndarray]) -> dict[str, float | int]:
    """The JSON summary of judged trials: ``trials``, ``successes``, ``success_rate``,
    ``timed_out`` (trials the time limit ended before their J-th junction, with no wrong exit
    and no stall failure: neither successes nor failures of the controller), ``junctions``,
    ``correct_junctions``, ``mean_stall_fraction``."""
    trials = int(verdict["success"].shape[0])
    successes = int(verdict["success"].sum())
    return {
        "trials": trials,
        "successes": successes,
        "success_rate": successes / trials if trials else 0.0,
        "timed_out": int(verdict["timed_out"].sum()),
        "junctions": int(verdict["judged"].sum()),
        "correct_junctions": int(verdict["correct"].sum()),
        "mean_stall_fraction": float(np.mean(verdict["stall"])) if trials else 0.0,
    }


def run_trials(
    maze: Maze,
    spec: TrialSpec,
    controller: Callable[[Any, Any], tuple[Any, tuple[Array, Array]]],
    initial_state: Callable[[int], Any],
    *,
    dt: float = 0.1,
    sensors: SensorConfig | None = None,
    camera: CameraConfig | None = None,
    record_every: int = 0,
    record_controller: bool = False,
    noise: NoiseConfig | None = None,
    key: Array | None = None,
    until_judged: bool = False,
) -> tuple[dict[str, np.ndarray], RolloutResult, np.ndarray]:
    """Run and judge every trial of ``spec`` in ``maze``.

    ``initial_state(n)`` gives the controller's batched initial state for ``n`` robots. The camera
    is on for "tiles" (default :class:`~mbn.world.engine.CameraConfig`) unless given. ``noise``
    (with its PRNG ``key``) and ``until_judged`` are the rollout's (:func:`run_trial_groups`).
    Returns the verdict of :func:`judge`, the rollout result and the start poses.
    """
    if camera is None and spec.behavior == "tiles":
        camera = CameraConfig()
    verdicts, result, _, poses = run_trial_groups(
        [maze],
        [TrialGroup("trials", 0, spec, initial_state)],
        controller,
        seconds=spec.seconds,
        dt=dt,
        sensors=sensors,
        camera=camera,
        record_every=record_every,
        record_controller=record_controller,
        noise=noise,
        key=key,
        until_judged=until_judged,
    )
    return verdicts["trials"], result, poses


def run_loaded_trials(
    maze: Maze,
    spec: TrialSpec,
    loaded: Any,
    key: Array | None = None,
    *,
    until_judged: bool = True,
) -> tuple[dict[str, np.ndarray], RolloutResult, np.ndarray]:
    """:func:`run_trials` of a controller made from a file
    (:class:`mbn.controllers.LoadedController`): its controller, initial state, robot step,
    sensors, camera and noise (``key``: the noise's PRNG key, needed when it is on). Each trial
    stops once judged unless ``until_judged`` is false (the rollout's statistics then cover the
    whole time limit)."""
    return run_trials(
        maze,
        spec,
        loaded.controller,
        loaded.initial_state,
        dt=loaded.dt,
        sensors=loaded.sensors,
        camera=loaded.camera,
        noise=loaded.noise,
        key=key,
        until_judged=until_judged,
    )


@dataclass(frozen=True)
class TrialGroup:
    """One test of a batch run by :func:`run_trial_groups`: ``spec`` in ``mazes[maze]``, the
    controller starting from ``initial_state(n)`` (its own network, program, ...)."""

    name: str
    maze: int
    spec: TrialSpec
    initial_state: Callable[[int], Any]


def run_trial_groups(
    mazes: list[Maze],
    groups: list[TrialGroup],
    controller: Callable[[Any, Any], tuple[Any, tuple[Array, Array]]],
    *,
    seconds: float,
    dt: float = 0.1,
    sensors: SensorConfig | None = None,
    camera: CameraConfig | None = None,
    record_every: int = 0,
    record_controller: bool = False,
    noise: NoiseConfig | None = None,
    key: Array | None = None,
    until_judged: bool = False,
) -> tuple[dict[str, dict[str, np.ndarray]], RolloutResult, dict[str, slice], np.ndarray]:
    """Run several tests of one controller function in one rollout (one compilation).

    Every group's trials (:func:`trial_starts`) are concatenated in group order, with their
    initial states; each group is judged by its own spec (its ``seconds`` is ignored: the batch
    runs ``seconds``). ``noise``: the rollout's noise (:class:`~mbn.world.sensors.NoiseConfig`;
    a controller that draws its own channels must be built with the same), ``key`` its PRNG key
    (required when it is on). ``until_judged``: each trial stops once its judged junctions are
    behind it (:func:`mbn.world.judged.run_rollout_until_judged`; the same verdicts, the
    rollout's other statistics up to that point; not with ``record_every``). Returns the
    verdicts by group name, the rollout result, each group's slice of the batch, and the start
    poses.
    """
    if not groups:
        raise MbnInputError("run_trial_groups needs at least one group")
    names = [g.name for g in groups]
    if len(set(names)) != len(names):
        raise MbnInputError(f"trial groups must have distinct names, got {names}")
    poses, index, states, slices = [], [], [], {}
    offset = 0
    for g in groups:
        if not 0 <= g.maze < len(mazes):
            raise MbnInputError(f"group {g.name!r}: maze index {g.maze} out of range")
        g.spec.check_maze(mazes[g.maze])
        p = trial_starts(mazes[g.maze], g.spec)
        poses.append(p)
        index.append(np.full(len(p), g.maze, np.int32))
        states.append(g.initial_state(len(p)))
        slices[g.name] = slice(offset, offset + len(p))
        offset += len(p)
    state = concatenate_states(states, [len(p) for p in poses])
    world = compile_mazes(mazes)
    junctions = junction_arrays(mazes, world)
    config = RolloutConfig(
        steps=max(1, round(seconds / dt)),
        dt=dt,
        sensors=sensors or SensorConfig(),
        camera=camera,
        record_every=record_every,
        record_controller=record_controller,
        max_junctions=max(8, *(g.spec.junctions for g in groups)),
        noise=noise or NoiseConfig(),
        # the sonars only as far as the inputs read them; a recorded trajectory keeps the
        # ranges themselves (the pictures draw them)
        sonar_reach=(
            None if record_every else input_reach(sensors or SensorConfig(), noise or NoiseConfig())
        ),
    )
    if config.noise.enabled and key is None:
        raise MbnInputError("the trials' noise is on: pass a PRNG key (a seed)")
    all_poses = np.concatenate(poses)
    # one compiled program per controller, config and shapes (run_rollout): the mazes are
    # arguments, not constants folded into the program
    if until_judged and not record_every:
        sizes = [len(p) for p in poses]
        result = run_rollout_until_judged(
            world,
            controller,
            state,
            put(all_poses),
            np.concatenate(index),
            config,
            judged=np.repeat([g.spec.junctions for g in groups], sizes),
            after_tile=np.repeat(
                [g.spec.behavior == "tiles" and g.spec.initial == "none" for g in groups], sizes
            ),
            junctions=junctions,
            key=key if config.noise.enabled else None,
        )
    else:
        result = run_rollout(
            world,
            controller,
            state,
            put(all_poses),
            put(np.concatenate(index)),
            config,
            junctions=junctions,
            key=key if config.noise.enabled else None,
        )
    stats = jax.tree.map(np.asarray, result.stats)  # sliced by group on the host
    verdicts = {
        g.name: judge(jax.tree.map(lambda a, s=slices[g.name]: a[s], stats), g.spec) for g in groups
    }
    return verdicts, result, slices, all_poses
