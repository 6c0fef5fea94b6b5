"""``mbn sweep --experiment switch``: the switch between programs over runs.

Each run's ``results.json`` records, per pair of programs, its sweep in brief (:func:`brief`):
the alphas, P1's share of the differing junction passes, the rates passing as each rule and
stalled, ``alpha_half`` and ``width``, and its claims. Over the runs, per pair: how many runs
meet each claim (and which do not), ``alpha_half`` and ``width`` as median [quartiles], and one
figure: every run's share curve and their median.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mbn.stats import describe

if TYPE_CHECKING:
    from mbn.experiments.pipeline.document import Section
    from mbn.experiments.stages.interpolation import InterpolationResult

__all__ = ["brief", "statistics", "switch_over_runs"]


def brief(data: InterpolationResult) -> dict[str, dict[str, Any]]:
    """A run's sweep per pair, for its ``results.json``."""
    out = {}
    for name, pair in data.pairs.items():
        pts = pair.points
        out[name] = {
            "first": pair.first,
            "second": pair.second,
            "alphas": [p.alpha for p in pts],
            "first_share": [p.first_share for p in pts],
            "as_first": [p.as_first / max(p.trials, 1) for p in pts],
            "as_second": [p.as_second / max(p.trials, 1) for p in pts],
            "stalled": [p.stalled / max(p.trials, 1) for p in pts],
            "trials": pts[0].trials if pts else 0,
            "alpha_half": pair.alpha_half,
            "width": pair.width,
        }
    return out


def statistics(runs: Mapping[int, Mapping[str, Any]]) -> dict[str, Any]:
    """Per pair over the runs that recorded it: the seeds, ``alpha_half`` and ``width``
    (median, quartiles; runs where it never crosses are counted apart) and, per claim of the
    runs' claims tables, the seeds that meet it and those that do not."""
    recorded = {s: r for s, r in sorted(runs.items()) if r.get("pairs")}
    pairs: dict[str, Any] = {}
    for seed, run in recorded.items():
        for name, b in run["pairs"].items():
            p = pairs.setdefault(name, {"seeds": [], "alpha_half": {}, "width": {}})
            p["seeds"].append(seed)
            p["alpha_half"][seed] = b["alpha_half"]
            p["width"][seed] = b["width"]
    for p in pairs.values():
        for key in ("alpha_half", "width"):
            values = [v for v in p[key].values() if v is not None]
            p[f"{key}_spread"] = {**describe(values), "runs": len(values)}
    claims: dict[str, dict[str, list[int]]] = {}
    for seed, run in recorded.items():
        for row in run.get("claims", []):
            c = claims.setdefault(row["claim"], {"target": row["target"], "met": [], "missed": []})
            if row["pass"] is not None:
                c["met" if row["pass"] else "missed"].append(seed)
    return {"runs": len(recorded), "seeds": list(recorded), "pairs": pairs, "claims": claims}


def switch_over_runs(
    out: Path, runs: Mapping[int, Mapping[str, Any]]
) -> tuple[dict[str, Any], list[Section], list[tuple[str, str]]]:
    """The statistics (for ``sweep.json``), the claims over runs and the pairs' table, and the
    figure (``out/figures/switch_share.png``)."""
    from mbn.experiments.pipeline.document import Section
    from mbn.viz.switch import share_over_runs

    stats = statistics(runs)
    n = stats["runs"]
    if not n:
        return stats, [], []
    claim_rows = [
        [claim, c["target"], f"{len(c['met'])}/{len(c['met']) + len(c['missed'])}",
         ", ".join(map(str, c["missed"])) or "–"]
        for claim, c in stats["claims"].items()
    ]  # fmt: skip

    def spread(s: dict[str, Any]) -> str:
        if not s["runs"]:
            return "–"
        return f"{s['median']:.2f} [{s['q1']:.2f}, {s['q3']:.2f}] ({s['runs']} runs)"

    pair_rows = [
        [name, spread(p["alpha_half_spread"]), spread(p["width_spread"])]
        for name, p in stats["pairs"].items()
    ]
    file = "figures/switch_share.png"
    share_over_runs({s: r["pairs"] for s, r in runs.items() if r.get("pairs")}, out / file)
    sections = [
        Section(
            "The switch between programs, over the runs",
            [
                f"{n} run{'s' * (n != 1)} (seeds {', '.join(map(str, stats['seeds']))}). "
                "Per claim, the runs that meet it and the seeds that do not (the criteria "
                "were stated before the runs: docs/switch.md). Per pair, where P1's share of "
                "the differing junction passes crosses one half, and the width in α from 10 % "
                "to 90 %: median [quartiles] over the runs where it crosses.",
            ],
            table=(["claim", "target", "runs meeting it", "seeds missing it"], claim_rows),
        ),
        Section(
            "Where the behaviour changes",
            table=(["pair P1:P2", "α at one half", "width (10 % to 90 %)"], pair_rows),
            images=[(file, "P1's share of the differing junction passes along α, every run")],
        ),
    ]
    return stats, sections, [(file, "the switch over runs")]
