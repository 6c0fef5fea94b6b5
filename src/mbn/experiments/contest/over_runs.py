"""Programs against dynamics over runs: what ``mbn sweep --experiment programs-vs-dynamics``
adds to its report, from each seed's ``results.json`` (``contest``) alone.

Per rule and contender: the runs that reached test success within the budget (k of N, Wilson
95 %), the median [IQR] of evaluations to success with unsuccessful runs censored at the budget,
the fraction of runs solved against evaluations, and the runs whose final best passes the test.
Per rule, program search against each dynamics contender: the ratio of median evaluations with
a bootstrap 95 % interval, the Mann–Whitney U test (its p-value also Holm-adjusted across the
rule's comparisons), the Vargha–Delaney A12 and the probability of improvement with a
stratified bootstrap interval (``mbn.stats``). The median run
of each contender (by evaluations to success, the lower of the two middle runs of an even
count) is named, with its controller file; and every run's evaluations, seed by seed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from mbn.experiments.pipeline.document import Section
from mbn.stats import (
    censored_quantiles,
    forward_transfer,
    holm,
    mann_whitney,
    median_ratio,
    probability_of_improvement,
    solved_curve,
    wilson_interval,
)

__all__ = ["checks_text", "contest_over_runs", "seed_table"]

#: The contender every other is compared with.
REFERENCE = "programs"

#: Seed of the bootstrap's resampling (NumPy's generator): the report is reproducible.
BOOTSTRAP_SEED = 0

#: The fewest runs per contender over which the 2016 claim is judged (the issue's 20 seeds).
MIN_RUNS = 20

#: The two-sided level of the Mann–Whitney test for a verdict.
ALPHA = 0.05

#: The claim of Donnarumma et al. (Adaptive Behavior 2016) the experiment measures.
CLAIM_2016 = "learning programs is better than learning dynamics (Donnarumma et al. 2016)"

#: What the claim over runs asks (the per-run claims row says it too).
CRITERION = (
    "program search faster than every dynamics contender on every rule (ratio of medians' 95 % "
    f"interval below 1, Mann–Whitney p, Holm-adjusted across the rule's comparisons, < {ALPHA}, "
    f"A12 < 0.5), over at least {MIN_RUNS} runs each"
)

#: The contenders that search programs, beside the reference: compared with it, not part of
#: the 2016 claim (which is about dynamics).
PROGRAM_SEARCHES = ("programs_k",)


def comparison_verdict(v: Mapping[str, Any]) -> str:
    """``faster``, ``slower`` or ``no clear difference`` for program search against one
    contender: faster where the Mann–Whitney p, Holm-adjusted across the comparisons of the
    rule's table (``p_holm``; the unadjusted p where a record has none), is below ``ALPHA``
    with A12 < 0.5 and the bootstrap interval of the ratio of medians lies below 1 (slower:
    p < ``ALPHA``, A12 > 0.5, the interval above 1)."""
    u, r = v["mann_whitney"], v["ratio"]
    p = u.get("p_holm", u["p"])
    if p is None or p >= ALPHA:
        return "no clear difference"
    high = r.get("high")
    low = r.get("low")
    if u["A12"] < 0.5 and high is not None and high < 1.0:
        return "faster"
    # an unbounded low end (None beside an unbounded ratio) lies above 1 too
    above = (low is not None and low > 1.0) or (low is None and bool(r.get("ratio_unbounded")))
    if u["A12"] > 0.5 and above:
        return "slower"
    return "no clear difference"


def claim_over_runs(stats: Mapping[str, Any]) -> dict[str, Any]:
    """The 2016 claim judged over the runs: it holds where program search is ``faster`` than
    every dynamics contender on every rule, and fails otherwise; with fewer than ``MIN_RUNS``
    runs of a contender it is not judged (``pass`` None), its figures given as preliminary."""
    parts, verdicts, fewest = [], [], None
    for rule, data in stats["rules"].items():
        for who, v in data["versus"].items():
            if who in PROGRAM_SEARCHES:
                continue
            verdict = comparison_verdict(v)
            verdicts.append(verdict)
            u = v["mann_whitney"]
            a12 = "–" if u["A12"] is None else f"{u['A12']:.2f}"
            p_used = u.get("p_holm", u["p"])
            p = "–" if p_used is None else f"{p_used:.3g}"
            parts.append(
                f"{rule}, programs : {who}: ratio {_ratio_text(v['ratio'])}, p (Holm) {p}, "
                f"A12 {a12}: {verdict}"
            )
        for c in data["contenders"].values():
            fewest = c["runs"] if fewest is None else min(fewest, c["runs"])
    judged = fewest is not None and fewest >= MIN_RUNS and bool(verdicts)
    measured = "; ".join(parts) if parts else "no comparison"
    if not judged:
        n = fewest or 0
        runs = f"{n} run{'s' * (n != 1)}"
        measured = f"preliminary, {runs} (a verdict needs {MIN_RUNS}): {measured}"
    return {
        "claim": CLAIM_2016,
        "measured": measured,
        "target": CRITERION,
        "pass": (all(v == "faster" for v in verdicts)) if judged else None,
    }


def _ft_text(ft: Mapping[str, Any] | None) -> str:
    """Forward transfer with its interval (sweeps summarized before it: none)."""
    if ft is None or math.isnan(ft["ft"]):
        return "–"
    return f"{ft['ft']:.2f} [{ft['low']:.2f}, {ft['high']:.2f}]"


def _pct(x: float | None) -> str:
    return "–" if x is None else f"{x:.0%}"


def _num(x: float | None) -> str:
    return "> budget" if x is None else f"{x:.0f}"


def _median_run(times: Mapping[int, float | None]) -> int:
    """The seed of the median run: runs sorted by evaluations to success (an unsolved run after
    every solved one, one solved at the budget included; then by seed), the lower middle one."""
    order = sorted(times, key=lambda s: (math.inf if times[s] is None else times[s], s))
    return order[(len(order) - 1) // 2]


def _through_interpreter(r: Mapping[str, Any], rule: str) -> bool | None:
    """Whether a run's final program passes the test run by the interpreter itself (its
    ``im_programs_RULE`` tests: every start mark, and the jittered target of the run's
    ``[contest]``), or None where the run has no such tests."""
    short = rule.replace("-", "_")
    tests = r.get("tests", {})
    marks, jitter = tests.get(f"im_programs_{short}"), tests.get(f"im_programs_{short}_jitter")
    if marks is None or jitter is None:
        return None
    target = float(r.get("config", {}).get("contest", {}).get("jitter_target", 0.95))
    return bool(marks["successes"] == marks["trials"] and jitter["success_rate"] >= target)


def checks_text(ways: list[str]) -> str:
    """How program search's checks ran over the runs (``[contest] program_checks``)."""
    said = {
        "interpreter": "through the fixed interpreter",
        "network": "on the network the program encodes",
    }
    if not ways:
        return "as no run recorded"
    if len(ways) == 1:
        return said[ways[0]]
    return "in some runs " + " and in others ".join(said[w] for w in ways)


def statistics(runs: Mapping[int, Mapping[str, Any]]) -> dict[str, Any]:
    """The statistics of the contest over the runs (``seed -> results.json``)."""
    per_rule: dict[str, Any] = {}
    rules: list[str] = []
    for r in runs.values():
        for rule in r.get("contest", {}):
            if rule not in rules:
                rules.append(rule)
    for rule in rules:
        contenders: dict[str, Any] = {}
        times: dict[str, dict[int, float | None]] = {}
        budget = None
        for seed, r in runs.items():
            for who, d in r.get("contest", {}).get(rule, {}).items():
                times.setdefault(who, {})[seed] = d["evaluations"]
                budget = d["budget"] if budget is None else budget
                if d["budget"] != budget:
                    raise ValueError(f"{rule}: runs with budgets {budget} and {d['budget']}")
        assert budget is not None
        for who, by_seed in times.items():
            t = list(by_seed.values())
            solved = sum(x is not None for x in t)
            final = sum(bool(runs[s]["contest"][rule][who]["final_success"]) for s in by_seed)
            e, frac = solved_curve(t, budget)
            median_seed = _median_run(by_seed)
            through = [_through_interpreter(runs[s], rule) for s in by_seed]
            interp: dict[str, Any] = {}
            if who == REFERENCE and through and all(x is not None for x in through):
                n_ok = sum(bool(x) for x in through)
                interp = {
                    "interpreter_success": n_ok,
                    "interpreter_wilson95": list(wilson_interval(n_ok, len(t))),
                }
            contenders[who] = {
                "runs": len(t),
                "solved": solved,
                "solved_wilson95": list(wilson_interval(solved, len(t))),
                "final_success": final,
                "final_wilson95": list(wilson_interval(final, len(t))),
                **interp,
                "evaluations": {str(s): v for s, v in by_seed.items()},
                **censored_quantiles(t, budget),
                "curve": {"evaluations": e.tolist(), "solved": frac.tolist()},
                "median_run": {
                    "seed": median_seed,
                    "evaluations": by_seed[median_seed],
                    "controller": f"seed-{median_seed}/controllers/contest_{rule}_{who}.json",
                },
            }
        versus: dict[str, Any] = {}
        if REFERENCE in times:
            a = list(times[REFERENCE].values())
            for who in times:
                if who == REFERENCE:
                    continue
                b = list(times[who].values())
                versus[who] = {
                    "ratio": median_ratio(a, b, budget, seed=BOOTSTRAP_SEED),
                    "mann_whitney": mann_whitney(a, b, budget),
                    # fewer evaluations is better: the scores are the evaluations negated, an
                    # unsolved run -infinity (ties with the other unsolved runs)
                    "improvement": probability_of_improvement(
                        _scores(a), _scores(b), seed=BOOTSTRAP_SEED
                    ),
                    # Continual World's forward transfer, the other contender as the reference
                    # (the scratch network: transfer from what the interpreter already holds)
                    "forward_transfer": forward_transfer(a, b, budget, seed=BOOTSTRAP_SEED),
                }
            adjusted = holm([v["mann_whitney"]["p"] for v in versus.values()])
            for v, p_holm in zip(versus.values(), adjusted, strict=True):
                v["mann_whitney"]["p_holm"] = p_holm
        per_rule[rule] = {"budget": budget, "contenders": contenders, "versus": versus}
    ways = sorted({str(r.get("program_checks", "network")) for r in runs.values()})
    out = {"rules": per_rule, "reference": REFERENCE, "program_checks": ways}
    out["claim"] = claim_over_runs(out)
    return out


def _scores(times: list[float | None]) -> list[float]:
    """Evaluations to success as scores where higher is better (an unsolved run: -inf)."""
    return [-math.inf if t is None else -float(t) for t in times]


def _ratio_text(r: Mapping[str, Any]) -> str:
    """``point [low, high]``: 0 and ∞ where a median (or an end) falls on an unsolved run."""

    def num(x: float) -> str:
        return "0" if x == 0 else f"{x:.2f}"

    if r["ratio"] is None and not r.get("ratio_unbounded"):
        return "undefined (both medians censored)"
    point = "∞" if r["ratio"] is None else num(r["ratio"])
    lo = ("∞" if r.get("ratio_unbounded") else "–") if r["low"] is None else num(r["low"])
    hi = "∞" if r["high"] is None else num(r["high"])
    return f"{point} [{lo}, {hi}]"


def seed_table(stats: Mapping[str, Any]) -> tuple[list[str], list[list[str]]] | None:
    """The evaluations to success of every run (``statistics``' ``evaluations``), one row per
    seed and one column per rule and contender; None where there are no runs."""
    columns = [(rule, who) for rule, data in stats["rules"].items() for who in data["contenders"]]
    seeds = sorted(
        {
            int(s)
            for rule, who in columns
            for s in stats["rules"][rule]["contenders"][who]["evaluations"]
        }
    )
    if not seeds:
        return None
    header = ["seed", *(f"{rule}: {who}" for rule, who in columns)]
    rows = []
    for s in seeds:
        row = [str(s)]
        for rule, who in columns:
            got = stats["rules"][rule]["contenders"][who]["evaluations"]
            row.append(_num(got[str(s)]) if str(s) in got else "–")
        rows.append(row)
    return header, rows


def contest_over_runs(
    out: Path, runs: Mapping[int, Mapping[str, Any]]
) -> tuple[dict[str, Any], list[Section], list[tuple[str, str]]]:
    """The contest's statistics (for ``sweep.json``), its report sections and figures: the
    solved curves (drawn into ``out/figures``) and each contender's median run's final best
    from its start marks (the picture its seed's report drew)."""
    from mbn.viz.contest import solved_curves

    stats = statistics(runs)
    secs: list[Section] = []
    images: list[tuple[str, str]] = []
    curves: dict[str, dict[str, Any]] = {}
    for rule, data in stats["rules"].items():
        rows = []
        for who, c in data["contenders"].items():
            lo, hi = c["solved_wilson95"]
            flo, fhi = c["final_wilson95"]
            q1, med, q3 = c["q1"], c["median"], c["q3"]
            m = c["median_run"]
            if "interpreter_success" in c:
                ilo, ihi = c["interpreter_wilson95"]
                interp_text = (
                    f"{c['interpreter_success']} of {c['runs']} [{_pct(ilo)}, {_pct(ihi)}]"
                )
            else:
                interp_text = "–"
            rows.append(
                [
                    who,
                    f"{c['solved']} of {c['runs']} [{_pct(lo)}, {_pct(hi)}]",
                    f"{_num(med)} [{_num(q1)}, {_num(q3)}]",
                    f"{c['final_success']} of {c['runs']} [{_pct(flo)}, {_pct(fhi)}]",
                    interp_text,
                    f"seed {m['seed']} (`{m['controller']}`)",
                ]
            )
            curves.setdefault(rule, {})[who] = (
                c["curve"]["evaluations"],
                c["curve"]["solved"],
                c["runs"],
            )
        vs_rows = []
        for who, v in data["versus"].items():
            u = v["mann_whitney"]
            poi = v.get("improvement")  # sweeps summarized before it: none
            vs_rows.append(
                [
                    f"{stats['reference']} : {who}",
                    _ratio_text(v["ratio"]),
                    "–" if u["U"] is None else f"{u['U']:.1f}",
                    "–" if u["p"] is None else f"{u['p']:.3g}",
                    "–" if u.get("p_holm") is None else f"{u['p_holm']:.3g}",
                    "–" if u["A12"] is None else f"{u['A12']:.2f}",
                    "–"
                    if poi is None or math.isnan(poi["p"])
                    else f"{poi['p']:.2f} [{poi['low']:.2f}, {poi['high']:.2f}]",
                    _ft_text(v.get("forward_transfer")),
                ]
            )
        secs.append(
            Section(
                f"Programs against dynamics: {rule}",
                [
                    f"Budget {data['budget']} evaluations per run. *Solved*: the run's best "
                    "passed the test (every start mark and the jittered target) within the "
                    "budget, with a Wilson 95 % interval; evaluations to success: median "
                    "[interquartile range], unsolved runs censored at the budget ('> budget': "
                    "the quantile falls on an unsolved run); *final*: the run's last best passes "
                    "the test as its network; *through the interpreter*: program search's last "
                    "program passes it run by the fixed interpreter itself, multipliers and all "
                    "(what an MBN would do with it). Program search's checks, and so its "
                    f"*solved* and evaluations, ran {checks_text(stats['program_checks'])}. "
                    "The median run (by evaluations to success) is named with its controller.",
                ],
                table=(
                    [
                        "contender",
                        "solved (Wilson 95 %)",
                        "evaluations to success, median [IQR]",
                        "final best passes",
                        "through the interpreter",
                        "median run",
                    ],
                    rows,
                ),
            )
        )
        if vs_rows:
            secs.append(
                Section(
                    f"Program search against each dynamics contender: {rule}",
                    [
                        "Ratio of median evaluations to success (below 1: program search needs "
                        "fewer) with a bootstrap 95 % interval (10 000 resamples of the runs; "
                        "a median that falls on an unsolved run counts as infinite, so a ratio "
                        "or an end of its interval can be 0 or unbounded); "
                        "the Mann–Whitney U test of the evaluations (unsolved runs tied with each "
                        "other, above every solved run; two-sided, normal approximation with "
                        "tie correction), its p-value adjusted by Holm's step-down method across "
                        "the comparisons of this table (p Holm), the "
                        "Vargha–Delaney A12 = P(program search needs more) (0.5: no "
                        "difference; below 0.5, program search is faster), and the probability "
                        "of improvement as rliable reports it, P(program search needs fewer) "
                        "with ties counted half, with a bootstrap 95 % interval that resamples "
                        "each contender's runs apart (2000 resamples). Forward transfer as "
                        "Continual World normalises it: (AUC − AUC_b) / (1 − AUC_b), the areas "
                        "under the solved-fraction curves over the budget, the other contender "
                        "the reference (against scratch: what the fixed interpreter transfers "
                        "to the new rule), with a bootstrap 95 % interval (2000 resamples).",
                    ],
                    table=(
                        [
                            "contenders",
                            "ratio [95 %]",
                            "U",
                            "p",
                            "p Holm",
                            "A12",
                            "P(improvement) [95 %]",
                            "forward transfer [95 %]",
                        ],
                        vs_rows,
                    ),
                )
            )
    claim = stats["claim"]
    holds = {True: "yes", False: "no", None: "not judged"}[claim["pass"]]
    secs.append(
        Section(
            "The 2016 claim over runs",
            [
                "Whether program search needs fewer evaluations to success than learning new "
                "dynamics, judged over the runs; the claim fails if any comparison is not "
                "'faster' (whichever way it falls, it is reported).",
            ],
            table=(
                ["claim", "measured", "target", "holds"],
                [[claim["claim"], claim["measured"], claim["target"], holds]],
            ),
            status=[claim["pass"]],
        )
    )
    per_seed = seed_table(stats)
    if per_seed is not None:
        secs.append(
            Section(
                "Evaluations to success, seed by seed",
                [
                    "Each run's evaluations to its first passed check, per rule and contender "
                    "('> budget': never passed; '–': the run has no such contender). The "
                    "statistics above are drawn from these numbers.",
                ],
                table=per_seed,
            )
        )
    for rule, data in stats["rules"].items():
        for who, c in data["contenders"].items():
            m = c["median_run"]["seed"]
            picture = f"seed-{m}/figures/contest_{rule}_{who}.png"
            if (out / picture).is_file():  # drawn by the seed's report
                images.append((picture, f"{rule}, {who}: the median run's final best (seed {m})"))
    if curves:
        budget = max(d["budget"] for d in stats["rules"].values())
        file = "figures/contest_solved.png"
        (out / "figures").mkdir(exist_ok=True)
        solved_curves(curves, budget, out / file)
        images.append((file, "Fraction of runs solved against evaluations, per contender"))
    return stats, secs, images
