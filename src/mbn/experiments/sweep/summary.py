"""Statistics over the seeds of a sweep, from each seed's ``results.json`` alone.

* per test: the seeds whose run meets its target (:mod:`~mbn.experiments.sweep.targets`), the
  distribution of the per-seed success rates (median, quartiles, min, max) and the pooled trials
  with a Wilson 95 % interval;
* per seed: which targets it misses (named), or the one-line error of a run that crashed;
* per claim of the claims table: in how many runs it holds.

Quartiles are NumPy's default (linear interpolation between order statistics, "type 7"). The
Wilson score interval of ``k`` successes in ``n`` trials at ``z`` = 1.96 is
``(p + z²/2n ± z sqrt(p(1-p)/n + z²/4n²)) / (1 + z²/n)`` with ``p = k/n``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from typing import Any

from mbn.experiments.stages.records import Tally
from mbn.experiments.sweep.specs import SweepSpec, sweep_spec
from mbn.experiments.sweep.targets import TARGETS, Target, measure, meets
from mbn.stats import Z95, describe, wilson_interval

__all__ = ["Z95", "describe", "seed_verdict", "summarize", "wilson_interval"]


#: What a run's claim names of its own (the LF's connections, "; here W_21, W_22, WE_22"): left
#: out when the claims of several runs are counted together.
_RUN_SPECIFIC = re.compile(r";\s*here [^)]*")


def claim_key(claim: str) -> str:
    """A claim as the runs share it: its text without what one run names of its own (the LF's
    connections), so that the claims of runs that chose other connections count together."""
    return _RUN_SPECIFIC.sub("", claim)


def seed_verdict(results: Mapping[str, Any], targets: Sequence[Target] = TARGETS) -> dict[str, Any]:
    """One run's targets: ``{"meets_all", "missed": [names], "targets": {name: {...}}}``."""
    per: dict[str, Any] = {}
    missed = []
    for t in targets:
        hits, trials = measure(t, dict(results))
        ok = meets(t, hits, trials)
        per[t.name] = {"hits": hits, "trials": trials, "meets": ok}
        if not ok:
            missed.append(t.name)
    return {"meets_all": not missed, "missed": missed, "targets": per}


def summarize(
    runs: Mapping[int, Mapping[str, Any] | None],
    errors: Mapping[int, str] | None = None,
    spec: SweepSpec | None = None,
    taken: Mapping[int, list[str]] | None = None,
) -> dict[str, Any]:
    """The statistics of a sweep.

    Args:
        runs: ``seed -> results.json`` of every seed (``None``: the seed has no finished run).
        errors: ``seed -> one-line error`` of the seeds whose run crashed.
        spec: the experiment's targets and tests (default: the reproduction's).
        taken: ``seed -> the stages its run took from another run`` (``--reuse``), recorded
            in its ``per_seed`` entry.

    Returns:
        ``{"seeds", "finished", "failed", "meet_every_target",
        "meet_every_generalization_target", "per_seed", "tests", "targets", "claims"}`` (plain
        JSON; the generalization targets are counted apart, None where the spec has none).
    """
    errors = dict(errors or {})
    spec = spec or sweep_spec(None)
    seeds = list(runs)
    finished = {s: r for s, r in runs.items() if r is not None}
    per_seed: dict[str, Any] = {}
    for s in seeds:
        r = runs[s]
        if r is None:
            per_seed[str(s)] = {
                "state": "failed" if s in errors else "missing",
                "error": errors.get(s),
            }
        else:
            v = seed_verdict(r, spec.targets)
            per_seed[str(s)] = {"state": "done", "meets_all": v["meets_all"], "missed": v["missed"]}
            if spec.generalization:
                g = seed_verdict(r, spec.generalization)
                per_seed[str(s)]["meets_generalization"] = g["meets_all"]
                per_seed[str(s)]["missed_generalization"] = g["missed"]
            if taken and taken.get(s):
                per_seed[str(s)]["taken"] = list(taken[s])
    tests: dict[str, Any] = {}
    for name in spec.tests:
        rates, succ, trials = [], 0, 0
        for s, r in finished.items():
            found = r.get("tests", {}).get(name)
            if found is None:
                continue
            tally = Tally.pick(found, f"seed {s}: test {name}")
            rates.append(float(tally.success_rate))
            succ += tally.successes
            trials += tally.trials
        lo, hi = wilson_interval(succ, trials)
        tests[name] = {
            "rates": rates,
            **describe(rates),
            "pooled": {"successes": succ, "trials": trials, "wilson95": [lo, hi]},
        }
    targets: dict[str, Any] = {}
    for t in (*spec.targets, *spec.generalization):
        measured = [measure(t, dict(r)) for r in finished.values()]
        hits = sum(h for h, _ in measured)
        trials = sum(n for _, n in measured)
        targets[t.name] = {
            "test": t.test,
            "source": t.source,
            "threshold": float(t.threshold),
            "what": t.what,
            "group": "generalization" if t in spec.generalization else "run",
            "seeds_meeting": sum(meets(t, h, n) for h, n in measured),
            "rates": [h / n if n else math.nan for h, n in measured],
            **describe([h / n for h, n in measured if n]),
            "pooled": {
                "hits": hits,
                "trials": trials,
                "wilson95": list(wilson_interval(hits, trials)),
            },
        }
    claims: dict[str, dict[str, Any]] = {}
    for r in finished.values():
        for c in r.get("claims", []):
            entry = claims.setdefault(
                claim_key(c["claim"]),
                {
                    "runs": 0,
                    "hold": 0,
                    "judged": 0,
                    "criterion": c.get("criterion", c.get("target", "")),
                },
            )
            entry["runs"] += 1
            entry["hold"] += int(bool(c["pass"]))
            # a claim a run does not judge (pass None: judged over runs, or not measured)
            entry["judged"] += int(c["pass"] is not None)
    return {
        "seeds": seeds,
        "finished": len(finished),
        "failed": sorted(s for s in errors if runs.get(s) is None),
        "meet_every_target": sum(bool(v.get("meets_all")) for v in per_seed.values()),
        "meet_every_generalization_target": (
            sum(bool(v.get("meets_generalization")) for v in per_seed.values())
            if spec.generalization
            else None
        ),
        "per_seed": per_seed,
        "tests": tests,
        "targets": targets,
        "claims": [{"claim": k, **v} for k, v in claims.items()],
    }
