"""Stage ``im_full``: a fully programmable interpreter of the run's RF — every connection of the
follower genome programmable (and the turning neuron's other two inputs, which a left-follower
may use), each in the genome's bounds — simulated by its structure, tested with the RF and LF
programs as the paper's interpreter is; and the paper's warning measured: the interpreter's
agreement with LF and RF as connections are made programmable one by one, from the paper's set
(the connections where RF and LF differ) to all of them."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from mbn.config import Locator, Settings, setting
from mbn.controllers import (
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    make_controller,
    save_controller,
)
from mbn.errors import MbnInputError
from mbn.experiments.named import follower_connections
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.pipeline.results import Record
from mbn.experiments.stages.common import MADE_BY, read_network, rf_lf_programs
from mbn.experiments.stages.keys import KEYS
from mbn.experiments.stages.protocol import AGREEMENT_TARGET, ROBUST_TARGET, SUFFIXES, test_specs
from mbn.experiments.stages.records import Agreement, TrialSummary
from mbn.experiments.stages.tests import TestsSettings
from mbn.experiments.trials import agreement, run_loaded_trials, summary
from mbn.networks.ctrnn import CTRNN
from mbn.networks.multiplier import load_multiplier
from mbn.networks.programmable import (
    Connection,
    Interpreter,
    Programmable,
    build_interpreter,
    differing_connections,
)
from mbn.notation import connection_name
from mbn.world.mazes.load import load_maze

__all__ = [
    "FULL_CONNECTIONS",
    "CurvePoint",
    "IMFullResult",
    "IMFullSettings",
    "IMFullStage",
    "full_interpreter",
    "full_interpreter_spec",
    "nested_sets",
    "reference_controller",
]

#: The follower genome (W 3 x 3, WE on the diagonal) and the turning neuron's two other inputs
#: (the LF search's candidates reach them), 0-based.
FULL_CONNECTIONS = (
    *(f"W[{i},{j}]" for i in range(3) for j in range(3)),
    *(f"WE[{k},{k}]" for k in range(3)),
    "WE[1,0]",
    "WE[1,2]",
)


@dataclass(frozen=True)
class IMFullSettings(Settings):
    """The fully programmable interpreter."""

    section = "im_full"
    connections: tuple[str, ...] = setting(
        FULL_CONNECTIONS,
        doc="the programmable connections in the code's 0-based form ('W[i,j]', 'WE[i,k]'; "
        "'W[1,2]' is the paper's W_23), in the order the agreement curve adds them",
        source="docs/behaviours.md (every connection of the follower genome, and LF's)",
    )
    bound: float = setting(
        20.0,
        doc="each programmable weight's range is [-bound, bound] (the genome's)",
        low=0.0,
        high=1e4,
        source="[followers] weight_bound",
    )
    tau_ratio: float = setting(
        0.0125,
        doc="the multipliers' time constant over the receiving neuron's",
        low=1e-4,
        high=1.0,
        source="docs/behaviours.md (tau/10: LF's program 87 %, tau/40: 98.5 % of seed 0's "
        "jittered; tau/80: RF's and LF's programs as faithful or more in 10 of 10 seeds, in 5 "
        "more so)",
    )
    substeps: int = setting(
        160,
        doc="interpreter steps per 0.1 s robot step (h / tau_m = 0.1, the multipliers' training "
        "step)",
        low=1,
        high=1000,
        source="docs/behaviours.md",
    )
    curve: bool = setting(
        True, doc="measure agreement against the number of programmable connections"
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        # connections RF has (3 neurons, 3 inputs), none twice
        follower_connections(self.connections, "im_full.connections")

    def check_names(self, sections: Mapping[str, Settings], where: Locator) -> None:
        # LF differs from RF in the triple of [lf_search] candidates it re-evolves: every one
        # must be programmable, or the interpreter could not run LF's program (found after LF)
        if "lf_search" not in sections:
            return
        search: Any = sections["lf_search"]
        mine = follower_connections(self.connections, "im_full.connections")
        for c in follower_connections(search.candidates, "lf_search.candidates"):
            if c not in mine:
                raise MbnInputError(
                    f"{where(self.section, 'connections')}: {c} is not listed, and LF may "
                    "re-evolve it ([lf_search] candidates): the interpreter could not run LF's "
                    "program"
                )


def nested_sets(first: list[Connection], order: list[Connection]) -> list[list[Connection]]:
    """The connection sets of the agreement curve: ``first`` (the paper's), then one more of
    ``order`` at a time (those not yet in), up to all of ``order`` and ``first``."""
    current = list(first)
    sets = [list(current)]
    for c in order:
        if c not in current:
            current.append(c)
            sets.append(list(current))
    return sets


def reference_controller(net: CTRNN, rule: str) -> Any:
    """The plain network (RF or LF) the interpreter's trials are compared with, loaded as the
    runs judge their controllers: an evolved network may step beyond its integrator's stability
    limit and still be what its stage kept and tested (refusing it here would end the run; the
    interpreter running its program is loaded so too, and its tests say how it drives)."""
    return make_controller(
        CTRNNControllerSpec(net=net, behavior=rule), None, where="im_full", check_stability=False
    )


def full_interpreter(
    rf: CTRNN, conns: list[Connection], mul: Any, s: IMFullSettings
) -> Interpreter:
    """The interpreter of ``rf`` with ``conns`` programmable in ``[-bound, bound]``, its
    multipliers at ``s.tau_ratio``."""
    return build_interpreter(
        rf, [Programmable(c, -s.bound, s.bound) for c in conns], mul, tau_ratio=s.tau_ratio
    )


def full_interpreter_spec(
    interp: Interpreter, rf: CTRNN, lf: CTRNN, s: IMFullSettings, meta: dict[str, Any]
) -> InterpreterControllerSpec:
    """The controller spec of ``interp`` with RF's and LF's programs, simulated by its blocks at
    ``s.substeps``; refuses RF or LF with a weight beyond ``s.bound``."""
    for name, net in (("RF", rf), ("LF", lf)):
        weights = np.asarray([c.value(net) for c in interp.connections])
        if np.any(np.abs(weights) > s.bound):
            raise MbnInputError(
                f"im_full.bound: {name}'s weights reach {np.max(np.abs(weights)):g}, beyond the "
                f"bound {s.bound:g}"
            )
    return InterpreterControllerSpec(
        interpreter=interp,
        programs=rf_lf_programs(interp, rf, lf),
        substeps=s.substeps,
        simulation="blocks",
        metadata=meta,
    )


@dataclass(frozen=True, kw_only=True)
class CurvePoint(Record):
    """A point of the agreement curve: the programmable connections (the last one added), and
    the interpreter's agreement with and success as RF and LF on the jittered test."""

    connections: list[str]
    agreement_rf: Agreement
    success_rf: TrialSummary
    agreement_lf: Agreement
    success_lf: TrialSummary

    def holds(self) -> bool:
        """Whether it meets the targets as both RF and LF (agreement and jittered success)."""
        return all(
            a.rate >= AGREEMENT_TARGET and t.success_rate >= ROBUST_TARGET
            for a, t in ((self.agreement_rf, self.success_rf), (self.agreement_lf, self.success_lf))
        )


@dataclass(frozen=True, kw_only=True)
class IMFullResult(Record):
    """What the ``im_full`` stage records (``stages/im_full.json``): the interpreter's
    connections and sizes, its time constants and step, its digest (which the stages that
    search its programs check), RF's and LF's programs, its tests and agreements with RF and
    LF (``im_full_rf``, ``im_full_rf_jitter``, ...), and the agreement curve over nested
    connection sets with the largest set that meets the targets (None when none does or the
    curve was not drawn)."""

    connections: list[str]
    connections_paper_notation: list[str]
    bound: float
    neurons: int
    multiplier_neurons: int
    tau_ratio: float
    multiplier_tau: float
    substeps: int
    step: float
    sha256: str
    programs: dict[str, list[float]]
    tests: dict[str, TrialSummary]
    agreement: dict[str, Agreement]
    curve: list[CurvePoint]
    largest_set_meeting_targets: int | None


class IMFullStage(Stage[IMFullResult]):
    name = "im_full"
    key_id = KEYS["im_full"]
    outputs = ("controllers/im_full.json",)
    needs = ("multiplier", "rf", "lf")
    settings = IMFullSettings
    result = IMFullResult

    def run(self, ctx: StageContext) -> IMFullResult:
        s: IMFullSettings = ctx.settings
        t = ctx.section(TestsSettings)
        rf, lf = read_network(ctx, "rf"), read_network(ctx, "lf")
        mul = load_multiplier(ctx.rundir.controller_file("multiplier"))
        conns = [Connection.parse(c) for c in s.connections]
        for c in differing_connections(rf, lf, margin=0.0):
            if c.connection not in conns:
                raise MbnInputError(
                    f"im_full.connections: LF differs from RF in {c.connection}, which is not "
                    "programmable: the interpreter could not run LF's program"
                )
        interp = full_interpreter(rf, conns, mul, s)
        meta = {"made_by": MADE_BY, "stage": self.name, "seed": ctx.seed}
        spec = full_interpreter_spec(interp, rf, lf, s, {**meta, "sha256": interp.digest()})
        save_controller(ctx.rundir.controller_file("im_full"), spec)

        mazes = {"": load_maze(t.maze), "_jitter": load_maze(t.maze)}
        mazes["_heldout"] = load_maze(t.heldout_maze)
        specs = {
            rule: test_specs(
                rule,
                seconds=t.seconds,
                jitter_per_mark=t.jitter_per_mark,
                heldout_repeats=t.heldout_repeats,
                test_seed=ctx.seeds["test_jitter"],
                heldout_seed=ctx.seeds["heldout_jitter"],
            )
            for rule in ("right", "left")
        }
        nets = {"right": rf, "left": lf}
        bar = ctx.progress.task("im_full tests", 2 * len(SUFFIXES))
        done = 0
        references: dict[str, dict[str, dict[str, np.ndarray]]] = {}
        tests: dict[str, Any] = {}
        agree: dict[str, Any] = {}
        for rule, short in (("right", "rf"), ("left", "lf")):
            plain = reference_controller(nets[rule], rule)
            emulated = make_controller(spec, rule, where="im_full", check_stability=False)
            references[rule] = {}
            for suffix in SUFFIXES:
                ref, _, _ = run_loaded_trials(mazes[suffix], specs[rule][suffix], plain)
                got, _, _ = run_loaded_trials(mazes[suffix], specs[rule][suffix], emulated)
                references[rule][suffix] = ref
                tests[f"im_full_{short}{suffix}"] = summary(got)
                agree[f"im_full_{short}{suffix}"] = agreement(got, ref)
                done += 1
                ctx.progress.update(bar, completed=done, info=f"{short}{suffix}")

        curve: list[CurvePoint] = []
        if s.curve:
            first = [p.connection for p in differing_connections(rf, lf, margin=0.0)]
            sets = nested_sets(first, conns)
            bar = ctx.progress.task("im_full agreement curve", len(sets))
            for k, subset in enumerate(sets):
                sub = full_interpreter_spec(full_interpreter(rf, subset, mul, s), rf, lf, s, meta)
                row: dict[str, Any] = {"connections": [str(c) for c in subset]}
                for rule, short in (("right", "rf"), ("left", "lf")):
                    got, _, _ = run_loaded_trials(
                        mazes["_jitter"],
                        specs[rule]["_jitter"],
                        make_controller(sub, rule, where="im_full curve", check_stability=False),
                    )
                    row[f"agreement_{short}"] = agreement(got, references[rule]["_jitter"])
                    row[f"success_{short}"] = summary(got)
                curve.append(CurvePoint.from_json(row))
                ctx.progress.update(bar, completed=k + 1, info=f"{len(subset)} connections")

        largest = max((len(r.connections) for r in curve if r.holds()), default=None)
        return IMFullResult(
            connections=[str(c) for c in interp.connections],
            connections_paper_notation=[connection_name(c) for c in interp.connections],
            bound=s.bound,
            neurons=int(interp.num_neurons),
            multiplier_neurons=int(interp.mul_size),
            tau_ratio=s.tau_ratio,
            multiplier_tau=float(s.tau_ratio * float(np.asarray(rf.tau).reshape(-1)[0])),
            substeps=s.substeps,
            step=0.1 / s.substeps,
            sha256=interp.digest(),
            programs={r: list(p) for r, p in spec.programs.items()},
            tests={k: TrialSummary.from_json(v) for k, v in tests.items()},
            agreement={k: Agreement.from_json(v) for k, v in agree.items()},
            curve=curve,
            largest_set_meeting_targets=largest,
        )

    def summary(self, data: IMFullResult) -> str:
        t, a = data.tests, data.agreement
        return (
            f"{len(data.connections)} programmable, {data.neurons} neurons; LF's program "
            f"{t['im_full_lf_jitter'].success_rate:.1%} jittered, agreement "
            f"{a['im_full_lf_jitter'].rate:.1%} (RF's {a['im_full_rf_jitter'].rate:.1%})"
        )
