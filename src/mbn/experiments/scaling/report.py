"""The figures, claims and report of ``mbn run scaling`` (``docs/scaling.md``)."""

from __future__ import annotations

from typing import Any

from mbn.experiments.generalization import GeneralizationResult, SplitRecord, meets_generalization
from mbn.experiments.pipeline import RunDir
from mbn.experiments.pipeline.document import Section, claims_section, write_document
from mbn.experiments.pipeline.results import RunResults
from mbn.experiments.stages.generalization import generalization_sections
from mbn.experiments.stages.scaling import KS, MBNKResult
from mbn.io import read_json
from mbn.stats import paired_difference

__all__ = ["FORGETTING_POINTS", "TITLE", "claims", "scaling_summary", "write_report"]

TITLE = "mbn: MBNs of 2 to 6 behaviours"

#: The forgetting target, stated before the runs: adding a behaviour changes the success of
#: those already there by at most this many percentage points (per run).
FORGETTING_POINTS = 2.0
#: Seed of the bootstrap's resampling of mazes (the report is reproducible).
BOOTSTRAP_SEED = 0


def _test(judged: GeneralizationResult, name: str, split: str = "test") -> SplitRecord | None:
    rec = judged.controllers.get(name)
    return None if rec is None else rec.splits.get(split)


def forgetting(judged: GeneralizationResult, k: int) -> dict[str, Any] | None:
    """What adding the K-th behaviour cost the K - 1 already there, as Continual World measures
    forgetting: the success, in percentage points, of the MBN of K behaviours on the test split
    of the K - 1 family minus that of the MBN of K - 1 behaviours on the same mazes and trials,
    with a percentile bootstrap interval that resamples the mazes (paired); None where either
    was not judged."""
    now, before = _test(judged, f"mbn_k{k}_on_tiles{k - 1}"), _test(judged, f"mbn_k{k - 1}")
    if now is None or before is None:
        return None
    names = [m.maze for m in before.mazes]
    if [m.maze for m in now.mazes] != names:
        raise ValueError(f"forgetting at K = {k}: the two judged other mazes")
    a = [100.0 * m.rate for m in now.mazes]
    b = [100.0 * m.rate for m in before.mazes]
    diff = paired_difference(a, b, seed=BOOTSTRAP_SEED)
    return {
        "points": 100.0 * (now.pooled.success_rate - before.pooled.success_rate),
        "low": diff["low"],
        "high": diff["high"],
        "mazes": len(names),
    }


#: The distances of the switch's table, in order (``generalization.tile_distances``).
DISTANCES = ("0", "1", "2", "3", "4+", "turn", "none")


def _switch_row(split: SplitRecord) -> dict[str, Any]:
    """An MBN on the switch's family: its pooled success and, by the tile's distance before
    the junction, the passes taking the rule's exit and the stalled share of the moves before
    them."""
    by = split.tile_distances or {}
    return {
        "success_rate": split.pooled.success_rate,
        "mazes_at_95": split.mazes_at_95,
        "mazes": len(split.mazes),
        "distances": {
            d: {
                "passes": by[d].passes,
                "correct": by[d].correct,
                "stall_fraction": by[d].stall_fraction,
            }
            for d in DISTANCES
            if d in by
        },
    }


def scaling_summary(stages: dict[str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per K (as text keys, for ``results.json``): the test split (pooled rate, mazes at 95 %,
    targets met), the zero-shot suite where there is one, forgetting (K > 2), the program
    module's code errors (worst, mean) and evaluations, and the new rule's program search
    attempts (K > 2)."""
    judged = GeneralizationResult.from_json(stages["generalization"])
    programs = stages.get("programs", {}).get("rules", {})
    out: dict[str, dict[str, Any]] = {}
    for k in KS:
        name = f"mbn_k{k}"
        if name not in stages:
            continue
        mbn = MBNKResult.from_json(stages[name])
        test, zero = _test(judged, name), _test(judged, name, "zero-shot")
        errors = list(mbn.code_errors.values())
        row: dict[str, Any] = {
            "tile_rules": mbn.tile_rules,
            "test": None
            if test is None
            else {
                "success_rate": test.pooled.success_rate,
                "successes": test.pooled.successes,
                "trials": test.pooled.trials,
                "mazes_at_95": test.mazes_at_95,
                "mazes": len(test.mazes),
                "meets": meets_generalization(test),
            },
            "zero_shot": None
            if zero is None or not zero.mazes
            else {
                "success_rate": zero.pooled.success_rate,
                "meets": zero.pooled.success_rate >= 0.9,
            },
            "forgetting": forgetting(judged, k) if k > min(KS) else None,
            "code_error_worst": max(errors),
            "code_error_mean": sum(errors) / len(errors),
            "pm_evaluations": mbn.evaluations,
            # genomes the PM's generations driving the robot evaluated (0: none ran)
            "pm_maze_evaluations": mbn.maze_evaluations,
            "grown": mbn.grown,
            "sha256_checked": mbn.sha256_checked,
        }
        turns = _test(judged, f"{name}_turns")
        row["turns"] = None if turns is None else _switch_row(turns)
        new_rule = mbn.tile_rules[-1]
        if k > 2 and new_rule in programs:
            row["program_attempts"] = len(programs[new_rule].get("attempts", [])) or 1
        out[str(k)] = row
    return out


def claims(stages: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """Per K: the MBN holds on its family's test split; the behaviours already there keep
    their success (K > 2); the interpreter is unchanged."""
    rows = []
    for k, row in scaling_summary(stages).items():
        t = row["test"]
        if t is not None:
            rows.append(
                {
                    "claim": f"the MBN of {k} behaviours holds in mazes of its family never "
                    "looked into (test split)",
                    "measured": f"{t['success_rate']:.1%} of {t['trials']} trials; "
                    f"{t['mazes_at_95']}/{t['mazes']} mazes at >= 95 %",
                    "target": ">= 95 % pooled and >= 90 % of the mazes at >= 95 %",
                    "pass": t["meets"],
                }
            )
        f = row["forgetting"]
        if f is not None:
            rows.append(
                {
                    "claim": f"adding behaviour {k} keeps the success of the {int(k) - 1} "
                    "already there (forgetting)",
                    "measured": f"{f['points']:+.1f} points [{f['low']:+.1f}, {f['high']:+.1f}] "
                    f"on the {f['mazes']} test mazes of tiles{int(k) - 1}",
                    "target": f"|change| <= {FORGETTING_POINTS:g} points",
                    "pass": abs(f["points"]) <= FORGETTING_POINTS,
                }
            )
        rows.append(
            {
                "claim": f"the interpreter is unchanged by the MBN of {k} behaviours",
                "measured": "sha256 checked before and after"
                if row["sha256_checked"]
                else "not checked",
                "target": "the run's sha256",
                "pass": bool(row["sha256_checked"]),
            }
        )
    return rows


def _switch_section(summary: dict[str, dict[str, Any]]) -> list[Section]:
    """The switch per K: the passes taking the rule's exit by the tile's distance before the
    junction, with the stalled share of the moves before them."""
    rows = []
    for k, row in summary.items():
        t = row.get("turns")
        if t is None:
            continue
        cells = [k, f"{t['success_rate']:.1%} ({t['mazes_at_95']}/{t['mazes']})"]
        for d in DISTANCES:
            x = t["distances"].get(d)
            if x is None:
                cells.append("-")
                continue
            stall = x["stall_fraction"]
            cells.append(
                f"{x['correct']}/{x['passes']}" + ("" if stall is None else f" ({stall:.1%})")
            )
        rows.append(cells)
    if not rows:
        return []
    return [
        Section(
            "The switch: the tile's distance before the junction",
            [
                "Each MBN on the test split of its switch family (turnsK: tiles 0 to 3 "
                "cells before junctions and on corners, the program changing in the middle of a "
                "turn): the judged junction passes that took the rule in force's exit, by how "
                "many free cells lay between the nearest tile and the junction (turn: the tile "
                "lay on the corner the corridor began at), and in brackets the stalled share of "
                "the robot's moves from the pass before."
            ],
            table=(["K", "pooled (mazes at 95 %)", *DISTANCES], rows),
        )
    ]


def write_report(rundir: RunDir) -> None:
    """``report.md``, ``report.html``, the figure against K and the generalization section."""
    from mbn.viz.scaling import against_k

    run = RunResults.pick(read_json(rundir.results), str(rundir.results))
    stages = {name: rundir.read_stage(name) for name in run.stages}
    summary = scaling_summary(stages)
    file = "figures/scaling.png"
    against_k({int(k): v for k, v in summary.items()}, rundir.root / file)
    table = []
    for k, row in summary.items():
        t, z, f = row["test"], row["zero_shot"], row["forgetting"]
        table.append(
            [
                k,
                ", ".join(row["tile_rules"]),
                "-" if t is None else f"{t['success_rate']:.1%} ({t['mazes_at_95']}/{t['mazes']})",
                "-" if z is None else f"{z['success_rate']:.1%}",
                "-" if f is None else f"{f['points']:+.1f} [{f['low']:+.1f}, {f['high']:+.1f}]",
                f"{row['code_error_worst']:.3f}",
                str(row["pm_evaluations"]),
            ]
        )
    secs = [
        Section(
            "What this run did",
            [
                f"Seed {run.seed}. The fixed interpreter's programs for the six priority rules "
                "(RF's and LF's, and four learned by program search alone), and MBNs of K = "
                "2 .. 6 behaviours, each grown from the one before by a tile kind, a program "
                "module neuron and a readout column; each judged on the test split of its tile "
                "family and, for K > 2, on that of K - 1 (forgetting; docs/scaling.md).",
            ],
        ),
        claims_section(claims(stages)),
        Section(
            "Against the number of behaviours",
            table=(
                [
                    "K",
                    "tile rules (1, 2, ... colours)",
                    "test split (mazes at 95 %)",
                    "zero-shot",
                    "forgetting (points) [95 %]",
                    "worst code error",
                    "PM evaluations",
                ],
                table,
            ),
            images=[(file, "success, forgetting and code error against K")],
        ),
        *_switch_section(summary),
        *generalization_sections(rundir, stages["generalization"]),
    ]
    write_document(rundir.root, "report", TITLE, secs)
