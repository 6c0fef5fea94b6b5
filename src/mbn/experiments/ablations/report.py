"""The claims and the report of ``mbn run ablations``."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from mbn.experiments.pipeline import RunDir
from mbn.experiments.pipeline.document import Section, claims_section, write_document
from mbn.experiments.pipeline.results import RunResults
from mbn.experiments.stages.ablations import AblationsStage, Variant
from mbn.io import read_json
from mbn.networks.programmable import DEFAULT_TAU_RATIO as PAPER_TAU_RATIO

__all__ = ["TITLE", "claims", "what", "write_report"]

TITLE = "mbn: ablations of the program path"


def _pct(value: float | None) -> str:
    return "-" if value is None else f"{value:.1%}"


def what(name: str, row: Variant) -> str:
    """What an ablation changed, with the interpreter it ran as recorded (the multipliers' time
    constant and sub-steps) where it ran one of its own."""
    interp = row.interpreter
    if interp is None:
        return row.what
    ran = f"multipliers at τ/{1 / interp.tau_ratio:g}, {interp.substeps} sub-steps"
    if name.startswith("tau_"):
        return ran + (", the paper's" if interp.tau_ratio == PAPER_TAU_RATIO else "")
    return f"{row.what}; {ran}"


def _agrees(row: Variant, test: str) -> float | None:
    """The interpreter's agreement on ``test`` (``rf_jitter``, ...), None where it did not
    change."""
    return None if row.agreement is None else row.agreement.get(test)


def claims(stages: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """What the ablations say about the paper's architecture."""
    rows = AblationsStage.from_json(stages[AblationsStage.name]).variants
    out = []
    base = rows.get("as_run")
    checks: tuple[tuple[str, Callable[[Variant], bool], str, str], ...] = (
        (
            "wrong_program",
            lambda r: r.mbn_jitter.rate < 0.5,
            "the program decides the behaviour: with the tiles swapped the MBN fails",
            "the MBN passes < 50 % of jittered trials",
        ),
        (
            "frozen_program",
            lambda r: r.mbn_jitter.rate < 0.5,
            "the program module's switching is needed: a frozen program fails",
            "the MBN passes < 50 % of jittered trials",
        ),
        (
            "tau_10",
            lambda r: r.mbn_jitter.rate >= 0.95,
            "the paper's multipliers an order of magnitude faster than the neurons (τ/10) suffice",
            "the MBN keeps >= 95 % of jittered trials at τ/{tau}",
        ),
        (
            "mul3",
            lambda r: r.mbn_jitter.rate >= 0.95,
            "the paper's 3-neuron multiplier suffices for the MBN",
            "the MBN keeps >= 95 % of jittered trials",
        ),
    )
    for name, check, claim, target in checks:
        if name not in rows:
            continue
        r = rows[name]
        if "{tau}" in target and r.interpreter is not None:  # the ratio it ran at, as recorded
            target = target.format(tau=f"{1 / r.interpreter.tau_ratio:g}")
        # a failure means something only where the run's MBN passes
        testable = name not in ("wrong_program", "frozen_program") or (
            base is not None and base.mbn_jitter.rate >= 0.95
        )
        out.append(
            {
                "claim": claim,
                "measured": f"{what(name, r)}: MBN {_pct(r.mbn_jitter.rate)} jittered, "
                f"{_pct(r.mbn_heldout.rate)} held out"
                + (
                    f"; agreement with RF {_pct(_agrees(r, 'rf_jitter'))}, with LF "
                    f"{_pct(_agrees(r, 'lf_jitter'))}"
                    if r.agreement is not None
                    else ""
                ),
                "target": target
                + ("" if testable else " (not testable: the run's MBN itself passes < 95 %)"),
                "pass": bool(check(r)) if testable else None,
            }
        )
    return out


def write_report(rundir: RunDir) -> None:
    """``report.md``, ``report.html`` and the bar chart."""
    from mbn.viz.ablations import ablation_bars

    run = RunResults.pick(read_json(rundir.results), str(rundir.results))
    stages = {name: rundir.read_stage(name) for name in run.stages}
    data = AblationsStage.from_json(stages[AblationsStage.name])
    rows = claims(stages)
    file = "figures/ablations.png"
    ablation_bars({k: v.to_json() for k, v in data.variants.items()}, rundir.root / file)
    table = []
    for name, r in data.variants.items():
        table.append(
            [
                name,
                what(name, r),
                f"{r.mbn_jitter.successes}/{r.mbn_jitter.trials}",
                f"{r.mbn_heldout.successes}/{r.mbn_heldout.trials}",
                *(
                    _pct(_agrees(r, test))
                    for test in ("rf_jitter", "lf_jitter", "rf_heldout", "lf_heldout")
                ),
            ]
        )
    secs = [
        Section(
            "What this run did",
            [
                f"Seed {run.seed}. The reproduction's MBN with one part of its program "
                "path changed at a time, on the jittered test maze "
                f"({data.trials.jitter_per_mark} trials per start mark) and the held-out "
                f"one ({data.trials.heldout_repeats} per mark); where the interpreter "
                "changes, its agreement with RF and LF on the same trials (docs/ablations.md).",
            ],
        ),
        claims_section(rows),
        Section(
            "Ablations",
            table=(
                [
                    "ablation",
                    "what",
                    "MBN jittered",
                    "MBN held-out",
                    "agrees RF (jit.)",
                    "agrees LF (jit.)",
                    "agrees RF (held)",
                    "agrees LF (held)",
                ],
                table,
            ),
            images=[(file, "MBN success and interpreter agreement per ablation")],
        ),
    ]
    write_document(rundir.root, "report", TITLE, secs)
