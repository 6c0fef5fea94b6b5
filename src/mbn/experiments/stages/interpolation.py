"""Stage ``interpolation``: the switch between two programs, swept. For each pair of programs
(P1, P2) of the fixed, fully programmable interpreter (``controllers/im_full_programs.json``:
RF's and LF's programs and the new rules'), the interpreter runs the program

    P(alpha) = alpha P1 + (1 - alpha) P2,        alpha = 0, 1/(steps - 1), ..., 1,

from every start mark of the first ``mazes`` mazes of its family's validation split (one batched
rollout for every pair and alpha), and each trial is judged by both rules: where the behaviour
changes from P2's to P1's, and how sharply (the share of junction passes, where the two rules
take different exits, that take P1's exit; the alpha where it crosses one half; the width from a
tenth to nine tenths). Beside it, the mechanism: the 3-neuron network each P(alpha) decodes to
(eq. 2, exact products) and its equilibria (:func:`mbn.networks.fixed_points.fixed_points`) at
the inputs the robot reads at the centre of each of the seven crossroads and in a corridor
(``docs/switch.md``). The interpreter's sha256 is checked against the run's."""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass
from typing import Any

import jax
import numpy as np

from mbn.config import Locator, Settings, setting
from mbn.controllers import (
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    make_controller,
    read_controller_spec,
)
from mbn.errors import MbnInputError
from mbn.experiments.named import locate
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.pipeline.results import Record, optional
from mbn.experiments.stages.im_full import IMFullStage
from mbn.experiments.stages.keys import KEYS
from mbn.experiments.stages.programs import check_digest, program_network
from mbn.experiments.stages.tests import TestsSettings
from mbn.experiments.trials import TrialGroup, TrialSpec, judge, route_seconds, run_trial_groups
from mbn.networks.ctrnn import CTRNN
from mbn.networks.fixed_points import fixed_points
from mbn.world.geometry import rect_segments, sonar_ranges
from mbn.world.mazes.model import Maze
from mbn.world.rules import parse_rule, parse_rules, rule_exit_codes
from mbn.world.sensors import SensorConfig, normalize, paper_inputs

__all__ = [
    "AlphaPoint",
    "Equilibrium",
    "InterpolationResult",
    "InterpolationSettings",
    "InterpolationStage",
    "PairSweep",
    "crossing",
    "probe_inputs",
]

_DOC = "docs/switch.md"

#: The probes of the fixed-point analysis: a corridor (the south arm's start of a crossroad)
#: and the centre of each of the seven crossroads, heading north.
PROBES = ("corridor", "L", "S", "R", "LS", "LR", "SR", "LSR")


@dataclass(frozen=True)
class InterpolationSettings(Settings):
    """The pairs of programs swept, the alphas and the trials of each."""

    section = "interpolation"
    pairs: tuple[str, ...] = setting(
        (
            "right:left",
            "straight-right:straight-left",
            "right:straight-right",
            "left:straight-left",
        ),
        doc="pairs of programs P1:P2 of the interpreter (rules it has programs for); "
        "P(alpha) = alpha P1 + (1 - alpha) P2",
        source=_DOC,
    )
    steps: int = setting(
        21,
        doc="alphas from 0 to 1, evenly spaced (both ends included)",
        low=2,
        high=1001,
        source=_DOC,
    )
    mazes: int = setting(
        10,
        doc="the first N mazes of the family's validation split the programs run in (every "
        "start mark once); never the test split",
        low=1,
        high=100,
        source=_DOC,
    )
    family: str = setting(
        "grid",
        doc="the maze family whose validation split the programs run in",
        source="docs/generalization.md",
    )
    fixed_points: bool = setting(
        True,
        doc="the equilibria of the network each P(alpha) decodes to, at the probes' inputs",
        source=_DOC,
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.pairs:
            raise MbnInputError("interpolation.pairs: at least one pair FIRST:SECOND")
        for text in self.pairs:
            _pair_rules(text)

    def check_names(self, sections: Any, where: Locator) -> None:
        # every rule of a pair has a program: RF's, LF's or one the programs stage learns
        if "programs" not in sections:
            return
        known = ("right", "left", *parse_rules(sections["programs"].rules, "programs.rules"))
        for k, text in enumerate(self.pairs):
            for rule in _pair_rules(text):
                if rule not in known:
                    at = locate(where, self.section, "pairs", k)
                    raise MbnInputError(
                        f"{at}: {rule} has no program: right and left are RF's and LF's, "
                        f"[programs] rules learns {', '.join(known[2:])}"
                    )


@dataclass(frozen=True, kw_only=True)
class Equilibrium(Record):
    """One equilibrium of a decoded network at a probe: its firing rates, whether it is
    stable, and the command it holds the robot at (``v`` m/s, ``w`` rad/s, positive left)."""

    rates: list[float]
    stable: bool
    v: float
    w: float


@dataclass(frozen=True, kw_only=True)
class AlphaPoint(Record):
    """One program P(alpha) of a pair: its trials judged by the first rule and by the second
    (``both``: a trial that passes by either, where the two took the same exits), its junction
    passes where the two rules differ (``differing``) and how many took each rule's exit, the
    stalls, and the equilibria of its decoded network by probe."""

    alpha: float
    trials: int
    as_first: int
    as_second: int
    both: int
    neither: int
    stalled: int
    differing: int
    first_exits: int
    second_exits: int
    equilibria: dict[str, list[Equilibrium]] | None = optional()

    @property
    def first_share(self) -> float | None:
        """The share of the differing junction passes that took the first rule's exit."""
        return self.first_exits / self.differing if self.differing else None


@dataclass(frozen=True, kw_only=True)
class PairSweep(Record):
    """A pair's sweep: the rules, one point per alpha, and where the exits change: the alpha
    where the first rule's share of the differing passes crosses one half (``alpha_half``) and
    the width from its crossing of 0.1 to that of 0.9 (None where it does not cross)."""

    first: str
    second: str
    points: list[AlphaPoint]
    alpha_half: float | None
    width: float | None


@dataclass(frozen=True, kw_only=True)
class InterpolationResult(Record):
    """What the ``interpolation`` stage records (``stages/interpolation.json``)."""

    sha256: str
    mazes: list[str]
    trials_per_program: int
    seconds: float
    probes: dict[str, list[float]]
    pairs: dict[str, PairSweep]


def crossing(alphas: list[float], shares: list[float | None], level: float) -> float | None:
    """The first alpha, going up from 0, where ``shares`` reaches ``level`` (linear between
    the two alphas around it); None where it never does or starts at or above it."""
    known = [(a, s) for a, s in zip(alphas, shares, strict=True) if s is not None]
    if not known or known[0][1] >= level:
        return None
    for (a0, s0), (a1, s1) in itertools.pairwise(known):
        if s1 >= level > s0:
            return a0 + (a1 - a0) * (level - s0) / (s1 - s0)
    return None


def probe_inputs(maze: Maze, pose: Any, sensors: SensorConfig) -> np.ndarray:
    """The paper's inputs I1..I3 (eq. 3) a robot reads at ``pose`` in ``maze`` (exact rays,
    no noise)."""
    ranges = np.asarray(sonar_ranges(np.asarray(pose, float), rect_segments(maze.solid_rects())))
    positions = sensors.paper_positions
    if positions is None:
        raise MbnInputError("interpolation: the sensors do not cast the paper's ten sonars")
    S = np.asarray(normalize(ranges[list(sensors.sonars)], sensors))
    return np.asarray(paper_inputs(S[list(positions)]), dtype=float)


def probes(sensors: SensorConfig) -> dict[str, np.ndarray]:
    """The inputs at each probe (:data:`PROBES`): a crossroad's start (the corridor) and the
    centre of each crossroad's junction, heading north."""
    from mbn.world.mazes.builtin import crossroad

    out: dict[str, np.ndarray] = {}
    for name in PROBES:
        maze = crossroad("LSR" if name == "corridor" else name)
        if name == "corridor":
            pose = maze.starts[0]
        else:
            xe, ye = maze.grid_edges()
            pose = np.array([(xe[0] + xe[-1]) / 2, (ye[0] + ye[-1]) / 2, np.pi / 2])
        out[name] = probe_inputs(maze, pose, sensors)
    return out


def equilibria(net: CTRNN, inputs: np.ndarray, motor: Any) -> list[Equilibrium]:
    """The equilibria of ``net`` at ``inputs``, with the command each holds."""
    out = []
    for p in fixed_points(net, inputs):
        speed, turn = p.rates[motor.speed_neuron], p.rates[motor.turn_neuron]
        out.append(
            Equilibrium(
                rates=[round(float(r), 6) for r in p.rates],
                stable=p.stable,
                v=round(float(motor.v_max * speed), 6),
                w=round(float(motor.w_max * (2.0 * turn - 1.0)), 6),
            )
        )
    return out


def _pair_rules(text: str) -> tuple[str, str]:
    """The two rules of a pair ``FIRST:SECOND`` (one line naming what is wrong)."""
    parts = text.split(":")
    if len(parts) != 2:
        raise MbnInputError(f"interpolation.pairs: {text!r} is not FIRST:SECOND")
    try:
        first, second = (parse_rule(p.strip()).name for p in parts)
    except MbnInputError as exc:
        raise MbnInputError(f"interpolation.pairs: {text!r}: {exc}") from None
    if first == second:
        raise MbnInputError(f"interpolation.pairs: {text!r} pairs a program with itself")
    return first, second


def _pair(text: str, programs: dict[str, Any]) -> tuple[str, str]:
    first, second = _pair_rules(text)
    missing = [r for r in (first, second) if r not in programs]
    if missing:
        raise MbnInputError(
            f"interpolation.pairs: the interpreter has no program for {', '.join(missing)} "
            f"(it has {', '.join(programs)})"
        )
    return first, second


class InterpolationStage(Stage[InterpolationResult]):
    name = "interpolation"
    key_id = KEYS["interpolation"]
    needs = ("rf", "im_full", "programs")
    settings = InterpolationSettings
    result = InterpolationResult

    def run(self, ctx: StageContext) -> InterpolationResult:
        from mbn.world.mazes import families
        from mbn.world.mazes.load import load_maze

        s: InterpolationSettings = ctx.settings
        path = ctx.rundir.controller_file("im_full_programs")
        spec = read_controller_spec(path)
        if not isinstance(spec, InterpreterControllerSpec):
            raise MbnInputError(f"{path}: not an interpreter")
        digest = ctx.read(IMFullStage).sha256
        check_digest(spec.interpreter, digest, "interpolation")
        rf_spec = read_controller_spec(ctx.rundir.controller_file("rf"))
        if not isinstance(rf_spec, CTRNNControllerSpec):
            raise MbnInputError(f"{ctx.rundir.controller_file('rf')}: not a CTRNN controller")
        programs = {k: np.asarray(v, dtype=float) for k, v in spec.programs.items()}
        pairs = [_pair(p, programs) for p in s.pairs]
        alphas = [round(float(a), 10) for a in np.linspace(0.0, 1.0, s.steps)]

        names = [
            f"{s.family}:{n}" for n in families.split_seeds("validation", 0, s.mazes - 1, s.family)
        ]
        mazes = [load_maze(n) for n in names]
        t = ctx.section(TestsSettings)
        trial = TrialSpec(behavior=pairs[0][0], repeats=1, seconds=t.seconds)
        seconds = max(trial.seconds, *(route_seconds(m, trial) for m in mazes))
        trial = dataclasses.replace(trial, seconds=seconds)

        groups, owners = [], []
        controller = None
        for p, (first, second) in enumerate(pairs):
            for i, a in enumerate(alphas):
                program = a * programs[first] + (1.0 - a) * programs[second]
                loaded = make_controller(
                    dataclasses.replace(spec, programs={"p": program.tolist()}),
                    "p",
                    where="interpolation",
                    check_stability=False,
                )
                controller = controller or loaded.controller
                for m in range(len(mazes)):
                    groups.append(TrialGroup(f"p{p}a{i}m{m}", m, trial, loaded.initial_state))
                    owners.append((p, i))
        assert controller is not None
        _, result, slices, _ = run_trial_groups(
            mazes, groups, controller, seconds=seconds, dt=spec.dt, sensors=spec.sensors
        )
        stats = jax.tree.map(np.asarray, result.stats)  # to the host once, sliced per group
        inputs = probes(rf_spec.sensors) if s.fixed_points else {}
        base = rf_spec.net

        out: dict[str, PairSweep] = {}
        for p, (first, second) in enumerate(pairs):
            spec_a, spec_b = (dataclasses.replace(trial, behavior=r) for r in (first, second))
            points = []
            for i, a in enumerate(alphas):
                tally = dict.fromkeys(
                    (
                        "trials",
                        "as_first",
                        "as_second",
                        "both",
                        "neither",
                        "stalled",
                        "differing",
                        "first_exits",
                        "second_exits",
                    ),
                    0,
                )
                for m in range(len(mazes)):
                    part = _slice(stats, slices[f"p{p}a{i}m{m}"])
                    va, vb = judge(part, spec_a), judge(part, spec_b)
                    ok_a, ok_b = np.asarray(va["success"]), np.asarray(vb["success"])
                    opened, exits = np.asarray(va["open"]), np.asarray(va["exits"])
                    ea, eb = rule_exit_codes(first, opened), rule_exit_codes(second, opened)
                    differ = (opened >= 0) & (ea != eb)
                    tally["trials"] += len(ok_a)
                    tally["as_first"] += int(ok_a.sum())
                    tally["as_second"] += int(ok_b.sum())
                    tally["both"] += int((ok_a & ok_b).sum())
                    tally["neither"] += int((~ok_a & ~ok_b).sum())
                    tally["stalled"] += int((np.asarray(va["stall"]) > 0.5).sum())
                    tally["differing"] += int(differ.sum())
                    tally["first_exits"] += int((differ & (exits == ea)).sum())
                    tally["second_exits"] += int((differ & (exits == eb)).sum())
                eq = None
                if s.fixed_points:
                    net = program_network(
                        spec.interpreter, base, a * programs[first] + (1.0 - a) * programs[second]
                    )
                    eq = {k: equilibria(net, v, rf_spec.motor) for k, v in inputs.items()}
                points.append(AlphaPoint(alpha=a, equilibria=eq, **tally))
            shares = [pt.first_share for pt in points]
            half = crossing(alphas, shares, 0.5)
            lo, hi = crossing(alphas, shares, 0.1), crossing(alphas, shares, 0.9)
            out[f"{first}:{second}"] = PairSweep(
                first=first,
                second=second,
                points=points,
                alpha_half=half,
                width=None if lo is None or hi is None else hi - lo,
            )
        return InterpolationResult(
            sha256=digest,
            mazes=names,
            trials_per_program=sum(
                slices[f"p0a0m{m}"].stop - slices[f"p0a0m{m}"].start for m in range(len(mazes))
            ),
            seconds=seconds,
            probes={k: [round(float(x), 6) for x in v] for k, v in inputs.items()},
            pairs=out,
        )

    def metrics(self, data: dict[str, Any]) -> dict[str, Any]:
        """``results.json`` keeps the sweep's shape, not every point (the stage's file has them,
        and the results' ``pairs`` each pair's curves)."""
        return {
            "sha256": data["sha256"],
            "mazes": data["mazes"],
            "trials_per_program": data["trials_per_program"],
            "pairs": {
                name: {k: pair[k] for k in ("first", "second", "alpha_half", "width")}
                for name, pair in data["pairs"].items()
            },
        }

    def summary(self, data: InterpolationResult) -> str:
        parts = []
        for name, pair in data.pairs.items():
            half = "-" if pair.alpha_half is None else f"{pair.alpha_half:.2f}"
            width = "-" if pair.width is None else f"{pair.width:.2f}"
            parts.append(f"{name}: switch at alpha {half} (width {width})")
        return "; ".join(parts)


def _slice(stats: Any, part: slice) -> Any:
    return jax.tree.map(lambda a: a[part], stats)
