"""The claims and the report of ``mbn run switch``."""

from __future__ import annotations

from typing import Any

from mbn.experiments.pipeline import RunDir
from mbn.experiments.pipeline.document import Section, claims_section, write_document
from mbn.experiments.pipeline.results import RunResults
from mbn.experiments.stages.interpolation import InterpolationResult, InterpolationStage, PairSweep
from mbn.io import read_json

__all__ = ["ENDS", "TITLE", "WIDTH", "claims", "write_report"]

TITLE = "mbn: the switch between programs"

#: The verdicts' criteria, stated before any run (docs/switch.md): each end of a sweep passes
#: as its own rule in at least ENDS of its trials; the switch is one step no wider than WIDTH in
#: alpha (the first rule's share of the differing exits from 0.1 to 0.9).
ENDS = 0.95
WIDTH = 0.25


def _pct(n: int, d: int) -> str:
    return f"{n}/{d} ({n / d:.0%})" if d else "-"


def _ends(pair: PairSweep) -> tuple[float, float]:
    last, first = pair.points[-1], pair.points[0]
    return last.as_first / max(last.trials, 1), first.as_second / max(first.trials, 1)


def claims(stages: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """Per pair: each program drives its own rule through the fixed interpreter; the behaviour
    changes in one narrow step of alpha."""
    data = InterpolationStage.from_json(stages[InterpolationStage.name])
    rows = []
    for name, pair in data.pairs.items():
        a1, a0 = _ends(pair)
        last, first = pair.points[-1], pair.points[0]
        rows.append(
            {
                "claim": f"{pair.first}'s and {pair.second}'s programs each drive their own rule "
                "through the fixed interpreter",
                "measured": f"α=1 passes as {pair.first} {_pct(last.as_first, last.trials)}; "
                f"α=0 as {pair.second} {_pct(first.as_second, first.trials)}",
                "target": f">= {ENDS:.0%} each",
                "pass": a1 >= ENDS and a0 >= ENDS,
            }
        )
        rows.append(
            {
                "claim": f"between {name.replace(':', ' and ')}, the behaviour switches in one "
                "narrow step of the program",
                "measured": "never crosses from 10 % to 90 %"
                if pair.width is None
                else f"{pair.first}'s exit from 10 % to 90 % of the differing passes within "
                f"α width {pair.width:.2f}, half at α {pair.alpha_half:.2f}",
                "target": f"width <= {WIDTH}",
                "pass": pair.width is not None and pair.width <= WIDTH,
            }
        )
    return rows


def _table(data: InterpolationResult) -> list[list[str]]:
    out = []
    for name, pair in data.pairs.items():
        for pt in pair.points:
            share = pt.first_share
            w_open = [e.w for e in (pt.equilibria or {}).get("LSR", []) if e.stable]
            out.append(
                [
                    name,
                    f"{pt.alpha:.2f}",
                    "-" if share is None else f"{share:.0%} of {pt.differing}",
                    _pct(pt.as_first, pt.trials),
                    _pct(pt.as_second, pt.trials),
                    _pct(pt.stalled, pt.trials),
                    ", ".join(f"{w:+.2f}" for w in w_open) or "-",
                ]
            )
    return out


def write_report(rundir: RunDir) -> None:
    """``report.md``, ``report.html`` and the figure."""
    from mbn.viz.switch import interpolation_figure

    run = RunResults.pick(read_json(rundir.results), str(rundir.results))
    stages = {name: rundir.read_stage(name) for name in run.stages}
    data = InterpolationStage.from_json(stages[InterpolationStage.name])
    file = "figures/interpolation.png"
    interpolation_figure(data.pairs, rundir.root / file)
    secs = [
        Section(
            "What this run did",
            [
                f"Seed {run.seed}. The fully programmable interpreter (sha256 "
                f"{data.sha256[:12]}…, unchanged) ran P(α) = α P1 + (1 − α) P2 for each pair, "
                f"{len(data.pairs[next(iter(data.pairs))].points)} values of α, from every "
                f"start mark of {len(data.mazes)} mazes of the validation split "
                f"({data.trials_per_program} trials a program, {data.seconds:g} s each); each "
                "trial judged by both rules. Below: the equilibria of the 3-neuron network "
                "each P(α) decodes to, at the inputs read at the centre of each crossroad "
                "(docs/switch.md).",
            ],
        ),
        claims_section(claims(stages)),
        Section("The sweep", images=[(file, "behaviour and equilibria along α")]),
        Section(
            "Every program",
            table=(
                [
                    "pair",
                    "α",
                    "P1's exit where they differ",
                    "passes as P1",
                    "passes as P2",
                    "stalled",
                    "w, stable, all open (rad/s)",
                ],
                _table(data),
            ),
        ),
    ]
    write_document(rundir.root, "report", TITLE, secs)
