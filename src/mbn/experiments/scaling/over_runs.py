"""``mbn sweep --experiment scaling``: the MBNs of K behaviours over runs.

Each run's ``results.json`` records, per K, its summary (:func:`~mbn.experiments.scaling.report.
scaling_summary`). Over the runs, per K: the runs meeting the test split's targets (Wilson
interval), the pooled rate's median [quartiles], the runs whose forgetting stays within the
target (the issue's: in at least 18 of 20), its median and range, the code error's median and
the program module's evaluations; a figure of every run's success and forgetting against K.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mbn.stats import describe, wilson_interval

if TYPE_CHECKING:
    from mbn.experiments.pipeline.document import Section

__all__ = ["FORGETTING_RUNS", "scaling_over_runs", "statistics"]

#: The share of runs whose forgetting must stay within the target (the issue: 18 of 20).
FORGETTING_RUNS = 0.9


def statistics(runs: Mapping[int, Mapping[str, Any]]) -> dict[str, Any]:
    """Per K over the runs that recorded it (``seed -> results.json``)."""
    from mbn.experiments.scaling.report import FORGETTING_POINTS

    recorded = {s: r["scaling"] for s, r in sorted(runs.items()) if r.get("scaling")}
    ks = sorted({int(k) for rows in recorded.values() for k in rows})
    out: dict[str, Any] = {}
    for k in ks:
        rows = {s: rows[str(k)] for s, rows in recorded.items() if str(k) in rows}
        tested = {s: r["test"] for s, r in rows.items() if r.get("test")}
        met = [s for s, t in tested.items() if t["meets"]]
        forgot = {s: r["forgetting"]["points"] for s, r in rows.items() if r.get("forgetting")}
        within = [s for s, f in forgot.items() if abs(f) <= FORGETTING_POINTS]
        out[str(k)] = {
            "runs": len(rows),
            "seeds": list(rows),
            "test_meets": len(met),
            "test_missed": [s for s in tested if s not in met],
            "test_meets_wilson95": list(wilson_interval(len(met), len(tested))),
            "test_rate": describe([t["success_rate"] for t in tested.values()]),
            "forgetting": {str(s): f for s, f in forgot.items()},
            "forgetting_within": len(within),
            "forgetting_runs": len(forgot),
            "forgetting_spread": describe(list(forgot.values())),
            "forgetting_meets": bool(forgot) and len(within) >= FORGETTING_RUNS * len(forgot),
            "code_error_worst": describe([r["code_error_worst"] for r in rows.values()]),
            "pm_evaluations": describe([float(r["pm_evaluations"]) for r in rows.values()]),
        }
    return {"runs": len(recorded), "seeds": list(recorded), "ks": out}


def scaling_over_runs(
    out: Path, runs: Mapping[int, Mapping[str, Any]]
) -> tuple[dict[str, Any], list[Section], list[tuple[str, str]]]:
    """The statistics (``sweep.json``), the table against K and the figure
    (``out/figures/scaling_over_runs.png``)."""
    from mbn.experiments.pipeline.document import Section
    from mbn.viz.scaling import against_k_over_runs

    stats = statistics(runs)
    if not stats["runs"]:
        return stats, [], []

    def pct(x: float) -> str:
        return f"{100 * x:.1f}"

    rows = []
    for k, s in stats["ks"].items():
        t = s["test_rate"]
        f = s["forgetting_spread"]
        missed = ", ".join(map(str, s["test_missed"])) or "–"
        rows.append(
            [
                k,
                f"{s['test_meets']}/{s['runs']} (missed: {missed})",
                f"{pct(t['median'])} [{pct(t['q1'])}, {pct(t['q3'])}]",
                "–"
                if not s["forgetting_runs"]
                else f"{s['forgetting_within']}/{s['forgetting_runs']} "
                f"({'met' if s['forgetting_meets'] else 'not met'}); median {f['median']:+.1f}, "
                f"{f['min']:+.1f} to {f['max']:+.1f}",
                f"{s['code_error_worst']['median']:.3f}",
                f"{s['pm_evaluations']['median']:.0f}",
            ]
        )
    file = "figures/scaling_over_runs.png"
    against_k_over_runs({s: r["scaling"] for s, r in runs.items() if r.get("scaling")}, out / file)
    n = stats["runs"]
    sections = [
        Section(
            "MBNs of K behaviours, over the runs",
            [
                f"{n} run{'s' * (n != 1)} (seeds {', '.join(map(str, stats['seeds']))}). Per K: "
                "the runs whose MBN meets the test split's targets (pooled >= 95 %, >= 90 % of "
                "the mazes at >= 95 %) and those that miss them; the pooled rate's median "
                "[quartiles] in percent; forgetting (the change on the K - 1 family's test "
                "mazes, points): the runs within ±2 points, against the issue's target of 18 "
                "of 20; the program module's worst code error and its evaluations, medians "
                "(docs/scaling.md).",
            ],
            table=(
                [
                    "K",
                    "test targets met",
                    "test pooled (%)",
                    "forgetting within ±2 points",
                    "worst code error",
                    "PM evaluations",
                ],
                rows,
            ),
            images=[(file, "every run's success and forgetting against K")],
        )
    ]
    return stats, sections, [(file, "MBNs of K behaviours over runs")]
