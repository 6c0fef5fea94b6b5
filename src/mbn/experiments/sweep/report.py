"""The report of a sweep: ``sweep.json``'s summary, ``sweep.md`` and a self-contained
``sweep.html`` (figures embedded), rendered from the sweep folder alone (each seed's
``results.json``, ``stages/`` and ``checkpoints/``); it never simulates, so ``mbn sweep
--summarize`` rebuilds it at any time.

The DE curves are read where the stages record them (:mod:`~mbn.experiments.sweep.specs`): for
a reproduction ``stages/rf.json``, ``lf.json`` and ``pm.json`` (``history.best``: the kept RF
restart's), and for the LF search the chosen triple's checkpoint ``checkpoints/lf_search_NN.npz``
(its history of best and mean fitness).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from mbn.errors import MbnInputError
from mbn.experiments.pipeline.document import Section, write_document
from mbn.experiments.pipeline.rundir import RunDir
from mbn.experiments.sweep.records import (
    ClaimOverRuns,
    Growth,
    ReusedStages,
    SweepFile,
    SweepHead,
    SweepSettingsRecord,
    SweepSummary,
)
from mbn.experiments.sweep.run import (
    SWEEP_FILE,
    finished_results,
    read_sweep,
    seed_dir,
    write_sweep,
)
from mbn.experiments.sweep.seeds import format_seeds
from mbn.experiments.sweep.specs import (
    SweepSpec,
    sweep_spec,
    with_recorded_tests,
)
from mbn.experiments.sweep.summary import summarize
from mbn.io import read_json
from mbn.viz.sweep import de_bands, rate_boxes

__all__ = ["de_curves", "summarize_folder", "summary_line"]


def de_curves(
    out: Path, seeds: list[int], spec: SweepSpec | None = None
) -> dict[str, dict[int, list[float]]]:
    """``stage -> seed -> best fitness per generation`` of the finished seeds, as recorded in
    their folders (stages without a record are left out); ``spec``: the experiment's sweep
    view (default: the reproduction's)."""
    spec = spec or sweep_spec(None)
    curves: dict[str, dict[int, list[float]]] = {name: {} for name in spec.de_stages}
    for s in seeds:
        rundir = RunDir(seed_dir(out, s))
        for name in spec.de_stages:
            curve = spec.curve(rundir, name)
            if curve:
                curves[name][s] = curve
    return {k: v for k, v in curves.items() if v}


def _pct(x: float | None) -> str:
    return "–" if x is None or x != x else f"{x:.1%}"


def _clock(seconds: float | None) -> str:
    if seconds is None:
        return "–"
    m, s = divmod(round(seconds), 60)
    h, m = divmod(m, 60)
    return f"{h} h {m:02d} min" if h else (f"{m} min {s:02d} s" if m else f"{s} s")


def summary_line(data: dict[str, Any]) -> str:
    """The sweep in one line: seeds meeting every target, failures named, wall time."""
    sweep = SweepFile.pick(data, SWEEP_FILE)
    summ = sweep.summary
    n = len(summ.seeds)
    if summ.judged:
        line = f"sweep: {summ.meet_every_target}/{n} seeds meet every target"
        if summ.meet_every_generalization_target is not None:
            line += f", {summ.meet_every_generalization_target}/{n} every generalization target"
    else:  # an experiment without per-run targets (compared over runs)
        line = f"sweep: {summ.finished}/{n} seeds finished (no per-run targets)"
    failed = [(s, sweep.run(s).error) for s in summ.failed]
    if failed:
        first = "; ".join(f"seed {s}: {e}" for s, e in failed[:3])
        more = f"; {len(failed) - 3} more" if len(failed) > 3 else ""
        line += f", {len(failed)} failed ({first}{more})"
    missing = [s for s, v in summ.per_seed.items() if v.state == "missing"]
    if missing:
        line += f", {len(missing)} not run"
    if sweep.seconds is not None:
        line += f", {_clock(sweep.seconds)}"
    return line


def _sections(
    out: Path,
    data: dict[str, Any],
    images: list[tuple[str, str]],
    spec: SweepSpec,
    extra: list[Section] | None = None,
) -> list[Section]:
    sweep = SweepFile.pick(data, str(out / SWEEP_FILE))
    summ = sweep.summary
    seeds = summ.seeds
    n = len(seeds)
    secs: list[Section] = []
    quick = " This is a **quick** sweep: tiny budgets, not the paper's figures." * bool(
        sweep.settings and sweep.settings.quick
    )
    secs.append(
        Section(
            "Sweep",
            [
                f"{n} seeds ({format_seeds(seeds)}), each a full `{spec.command}` run in "
                f"`seed-K/`; {summ.finished} finished, {len(summ.failed)} failed. "
                + (
                    f"**{summ.meet_every_target} of {n} seeds meet every target.**"
                    if summ.judged
                    else "The runs have no per-run targets: they are compared over runs."
                )
                + quick
                + _grown_text(sweep.grown)
                + (_combined_text(sweep.combined) if sweep.combined else ""),
                summary_line(data) + ".",
            ],
        )
    )
    secs.extend(extra or [])
    target_of = {t.test: t for t in spec.targets if t.source == "tests"}
    rows, status = [], []
    for name in spec.tests:
        t = summ.tests[name]
        tg = target_of.get(name)
        met = summ.targets[tg.name].seeds_meeting if tg else None
        lo, hi = t.pooled.wilson95
        rows.append(
            [
                name,
                tg.label if tg else "–",
                "–" if met is None else f"{met}/{summ.finished}",
                f"{_pct(t.median)} [{_pct(t.q1)}, {_pct(t.q3)}]",
                _pct(t.min),
                f"{t.pooled.successes}/{t.pooled.trials}",
                f"[{_pct(lo)}, {_pct(hi)}]",
            ]
        )
        status.append(None if met is None else met == summ.finished and met > 0)
    for tg in spec.targets:
        if tg.source != "agreement":
            continue
        a = summ.targets[tg.name]
        lo, hi = a.pooled.wilson95
        rows.append(
            [
                f"agreement {tg.test}",
                tg.label,
                f"{a.seeds_meeting}/{summ.finished}",
                f"{_pct(a.median)} [{_pct(a.q1)}, {_pct(a.q3)}]",
                _pct(a.min),
                f"{a.pooled.hits}/{a.pooled.trials}",
                f"[{_pct(lo)}, {_pct(hi)}]",
            ]
        )
        status.append(a.seeds_meeting == summ.finished and a.seeds_meeting > 0)
    secs.append(
        Section(
            "Tests over seeds",
            [
                "Per test: its per-run target, how many seeds meet it, the success rates over "
                "the seeds (median [interquartile range], min), and the trials of every seed "
                "pooled with a Wilson 95 % interval. " + spec.targets_text,
            ],
            table=(
                ["test", "target", "seeds meeting", "median [IQR]", "min", "pooled", "Wilson 95 %"],
                rows,
            ),
            status=status,
        )
    )
    secs.append(_seeds_section(sweep, seeds))
    claims = summ.claims
    if claims or not summ.finished:  # runs that make no claim (a lab's own may make none)
        secs.append(
            Section(
                "Claims over runs",
                [
                    f"Each claim of the claims table, and in how many of the {summ.finished} "
                    "finished runs it holds (each run judges it by the criterion shown)."
                ],
                table=(
                    ["claim", "criterion", "runs reproducing it"],
                    [[c.claim, c.criterion, _claim_count(c)] for c in claims],
                ),
                status=[None if c.judged_runs == 0 else c.hold == c.judged_runs for c in claims],
            )
        )
    secs.append(Section("Figures", [], images=images))
    return secs


def _grown_text(grown: list[Growth]) -> str:
    """Where a sweep gained seeds, which it held before each time (its seeds' runs were made
    in installments; each run records its own code and time)."""
    if not grown:
        return ""
    steps = "; then ".join(f"seeds {format_seeds(g.seeds_before)} until {g.at}" for g in grown)
    return f" The sweep grew: it held {steps}."


def _combined_text(combined: list[dict[str, Any]]) -> str:
    """The installments a combined sweep was made of, in one sentence for its report."""
    parts = []
    for c in combined:
        code = c.get("code") or {}
        commit = code.get("commit") or code.get("package_sha256") or "unrecorded code"
        seeds = [int(s) for s in c.get("seeds") or []]
        parts.append(
            f"seed{'s' * (len(seeds) != 1)} {format_seeds(seeds)} from `{c.get('folder')}` "
            f"(code {str(commit)[:7]})"
        )
    return " Combined from installments: " + "; ".join(parts) + "."


def _claim_count(c: ClaimOverRuns) -> str:
    """'k of N' runs reproducing a claim; where some runs could not judge it (their verdict
    None: e.g. an ablation of an MBN that itself fails), 'k of J judged (N - J not testable)';
    a claim no run judges is 'not judged per run' (an experiment's analysis over runs may judge
    it)."""
    judged = c.judged_runs
    if judged == 0:
        return f"not judged per run ({c.runs} runs)"
    if judged < c.runs:
        return f"{c.hold} of {judged} judged ({c.runs - judged} not testable)"
    return f"{c.hold} of {c.runs}"


def summarize_folder(out: Path) -> dict[str, Any]:
    """Summarize the sweep in ``out`` from its folder alone: the statistics into
    ``sweep.json`` (``summary``), the figures into ``figures/``, ``sweep.md`` and
    ``sweep.html``. Returns ``sweep.json``."""
    out = Path(out)
    data = read_sweep(out)
    head = SweepHead.pick(data, str(out / SWEEP_FILE))
    settings = head.settings or SweepSettingsRecord(seeds=[], quick=False)
    spec = sweep_spec(settings.experiment)
    seeds = [int(s) for s in settings.seeds]
    # the sweep's recorded config, checked as this version reads it, compared as recorded
    spec.load().config_from_dict(settings.config, str(out / SWEEP_FILE))
    runs: dict[int, dict[str, Any] | None] = {}
    for s in seeds:  # a kept installment's seeds hold their results only (sweep.combine)
        runs[s] = finished_results(out, s, dict(settings.config or {}))
    errors = {
        s: str(head.run(s).error)
        for s in seeds
        if runs[s] is None and head.run(s).state == "failed"
    }
    spec = with_recorded_tests(spec, runs)
    finished = [s for s in seeds if runs[s] is not None]
    summ = summarize(runs, errors, spec, taken=finished_taken(out, finished))
    images: list[tuple[str, str]] = []
    (out / "figures").mkdir(exist_ok=True)
    extra: list[Section] = []
    if spec.analysis is not None:
        completed = {s: r for s, r in runs.items() if r is not None}
        analysis, extra, more = spec.analysis(out, completed) if completed else ({}, [], [])
        summ = {**summ, "analysis": analysis}
        images.extend(more)
    data = {**data, "summary": summ}
    summary = SweepSummary.pick(summ, str(out / SWEEP_FILE))
    if spec.generalization and finished:
        extra.append(_generalization_section(out, summary, runs, spec))
    if finished:
        curves = de_curves(out, finished, spec)
        if curves:
            de_bands(curves, dict(spec.de_stages), out / "figures" / "sweep_de.png")
            images.append(
                (
                    "figures/sweep_de.png",
                    "DE best fitness per generation: min–max and interquartile bands "
                    "over the seeds, the median run drawn",
                )
            )
        rates = {n: summary.numbers(summary.tests[n].rates) for n in spec.tests}
        thresholds = {t.test: float(t.threshold) for t in spec.targets if t.source == "tests"}
        for t in spec.targets:
            if t.source == "agreement":
                rates[f"agree {t.test}"] = summary.numbers(summary.targets[t.name].rates)
                thresholds[f"agree {t.test}"] = float(t.threshold)
        groups = [(title, list(tests)) for title, tests in spec.groups]
        groups.append(
            ("Interpreter agreement (jittered)", [k for k in rates if k.startswith("agree ")])
        )
        if any(tests for _, tests in groups):  # runs that record no tests: no box plot
            rate_boxes(rates, thresholds, out / "figures" / "sweep_rates.png", groups)
            images.append(
                (
                    "figures/sweep_rates.png",
                    "Per-seed success rates of each test (dots: seeds; red: the target)",
                )
            )
    write_sweep(out, data)
    write_document(out, "sweep", spec.title, _sections(out, data, images, spec, extra))
    return data


def _generalization_section(
    out: Path,
    summ: SweepSummary,
    runs: dict[int, dict[str, Any] | None],
    spec: SweepSpec,
) -> Section:
    """The sweep's generalization: per seed, each generalization target (test split pooled and
    mazes at 95 %, zero-shot pooled) met or not with its figure, and the performance profile on
    the test split (one curve per seed, a panel per controller)."""
    from mbn.experiments.generalization import GeneralizationResult
    from mbn.experiments.pipeline.results import RunResults
    from mbn.experiments.stages.generalization import GeneralizationStage
    from mbn.experiments.sweep.targets import measure, meets
    from mbn.viz.generalization import performance_profile_panels

    names = [t.name for t in spec.generalization]
    rows: list[list[str]] = []
    status: list[bool | None] = []
    profiles: dict[str, dict[str, list[float]]] = {}
    for s, r in runs.items():
        if r is None:
            continue
        cells = []
        for t in spec.generalization:
            hits, trials = measure(t, r)
            ok = meets(t, hits, trials)
            cells.append(f"{hits}/{trials}" + ("" if ok else " ✗") if trials else "–")
        v = summ.per_seed[str(s)]
        rows.append([str(s), *cells, "yes" if v.meets_generalization else "no"])
        status.append(bool(v.meets_generalization))
        found = RunResults.pick(r, f"seed {s}: results.json").stages.get(GeneralizationStage.name)
        gen = GeneralizationResult.pick(found, f"seed {s}: generalization") if found else None
        for name, rec in (gen.controllers if gen else {}).items():
            test = rec.splits.get("test")
            if test:
                profiles.setdefault(name, {})[f"seed {s}"] = [m.rate for m in test.mazes]
    images = []
    if profiles:
        performance_profile_panels(profiles, out / "figures" / "sweep_profile.png")
        images.append(
            (
                "figures/sweep_profile.png",
                "Test split: fraction of the mazes at a success rate of at least x, one curve "
                "per seed",
            )
        )
    count = summ.meet_every_generalization_target
    return Section(
        "Generalization over seeds",
        [
            f"**{count} of {len(summ.seeds)} seeds meet every generalization target**: on "
            "the test split (100 mazes drawn from the family before any run, used by no "
            "selection) pooled success >= 95 % and >= 90 % of the mazes each at >= 95 %, and "
            "pooled >= 90 % on the zero-shot suite, for each controller. Cells: hits/trials "
            "(mazes at 95 %/mazes for the second of each); ✗ marks a miss "
            "(`docs/generalization.md`)."
        ],
        table=(["seed", *names, "meets every one"], rows),
        status=status,
        images=images,
    )


def finished_taken(out: Path, seeds: list[int]) -> dict[int, list[str]]:
    """Per seed, the stages its run took from another run (``--reuse``: ``run.json``'s
    ``reused``), where it took any (a ``run.json`` that cannot be read counts as none)."""
    taken: dict[int, list[str]] = {}
    for seed in seeds:
        path = seed_dir(out, seed) / "run.json"
        try:
            reused = ReusedStages.pick(read_json(path), str(path)).reused if path.exists() else []
        except MbnInputError:
            reused = []
        names = [n for entry in reused or [] for n in entry.stages]
        if names:
            taken[seed] = names
    return taken


def _seeds_section(sweep: SweepFile, seeds: list[int]) -> Section:
    """One row per seed: its state, the targets it missed (or its error) and its time; an
    experiment without per-run targets has no "meets every target" column (a finished run is
    only finished: its figures are compared over the runs)."""
    summ = sweep.summary
    judged = summ.judged
    rows: list[list[str]] = []
    status: list[bool | None] = []
    for s in seeds:
        v = summ.per_seed[str(s)]
        clock = _clock(sweep.run(s).seconds)
        if v.taken:  # --reuse: the time is of the stages it ran
            clock += f" (took {', '.join(v.taken)} from another run)"
        if v.state == "done":
            if judged:
                missed = ", ".join(v.missed or []) or "none"
                rows.append([str(s), "done", missed, clock, "yes" if v.meets_all else "no"])
                status.append(v.meets_all)
            else:
                rows.append([str(s), "done", "–", clock])
                status.append(None)
        else:
            rows.append([str(s), v.state, v.error or "–", clock, *(["no"] * judged)])
            status.append(False if judged or v.state == "failed" else None)
    if judged:
        header = ["seed", "run", "targets missed (or error)", "time", "meets every target"]
        text = "Targets missed are named; a run that crashed shows its error."
    else:
        header = ["seed", "run", "error", "time"]
        text = (
            "The runs have no per-run targets (a finished run is compared over the runs, "
            "above); a run that crashed shows its error, one not run yet is 'missing'."
        )
    return Section(
        "Seeds",
        ["Each seed's run folder is `seed-K/` (its own `report.html`). " + text],
        table=(header, rows),
        status=status,
    )
