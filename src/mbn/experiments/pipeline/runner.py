"""The runner: an experiment's stages in order into a run folder, resumable, then ``results.json``
and the report.

Seeds: the run's seed becomes one JAX key here (``jax.random.key(seed)``); stage ``s`` draws from
``fold_in(key, s.key_id)``; seeds of NumPy edges (jittered starts) are derived by the experiment
and recorded in ``results.json``. A run's effective config (defaults, then the ``quick`` preset
when asked, then a settings file) is written whole to ``run.json`` and ``results.json``;
``--resume`` refuses a config that differs from the run's.

Timings: ``timings.json`` (:meth:`RunDir.write_timings`) records, for each stage the runner
runs, its wall-clock seconds (``stages``) and the robot-steps counted in this process while it
ran (``robot_steps``: :func:`mbn.world.rollout.robot_steps` after it less before; 0 for a stage
that launches no rollout, or whose rollouts are not counted), and the same for the results and
the report (``report``). A resumed run keeps the entries of the stages done before (both fields,
as they were recorded; a file written before ``robot_steps`` existed has none for them); a stage
taken from another run (``--reuse``) or not run (a partial run) has an entry in neither: its
time was spent elsewhere, or not at all. :mod:`~mbn.experiments.pipeline.timings` prints them
as a table.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import jax

from mbn.config import Settings
from mbn.errors import MbnInputError
from mbn.experiments.pipeline.context import StageContext
from mbn.experiments.pipeline.document import plain_report
from mbn.experiments.pipeline.experiment import Experiment
from mbn.experiments.pipeline.progress import Progress
from mbn.experiments.pipeline.registry import Registry, Stage
from mbn.experiments.pipeline.reuse import ReuseSource, check_agreement, take_stages
from mbn.experiments.pipeline.runconfig import RunConfig, RunSettings, first_difference
from mbn.experiments.pipeline.rundir import RunDir
from mbn.io import check_writable, write_json_atomic
from mbn.precision import scope
from mbn.provenance import code_difference, code_identity, environment
from mbn.world.rollout import robot_steps

__all__ = [
    "Experiment",
    "RunConfig",
    "RunSettings",
    "check_out_dir",
    "collect_results",
    "first_difference",
    "prepare",
    "replace_section",
    "run_experiment",
    "run_stage",
    "versions",
]


def versions() -> dict[str, str]:
    """Versions of what the results depend on (:func:`mbn.provenance.environment`)."""
    return dict(environment())


def check_out_dir(out: Path, kind: str, *, resume: bool, force: bool) -> None:
    """Refuse an output folder that holds something else (one clear line).

    A folder holding another run (``run.json``) is used only with ``resume`` (continue it) or
    ``force`` (start anew); a folder holding other files is never used; a file is refused.
    """
    if resume and force:
        raise MbnInputError("--resume and --force exclude each other")
    if out.exists() and not out.is_dir():
        raise MbnInputError(f"--out {out}: is a file, not a folder")
    if not out.exists():
        if resume:
            raise MbnInputError(f"--out {out}: nothing to resume (the folder does not exist)")
        return
    if not any(out.iterdir()):
        if resume:
            raise MbnInputError(f"--out {out}: nothing to resume (the folder is empty)")
        return
    rundir = RunDir(out)
    if not rundir.manifest.exists():
        raise MbnInputError(
            f"--out {out}: the folder holds other files and no run (run.json); choose an empty "
            "or new folder"
        )
    data = rundir.read_manifest()
    if data.get("kind") != kind:
        raise MbnInputError(f"{rundir.manifest}: not a {kind} run (kind {data.get('kind')!r})")
    if not (resume or force):
        raise MbnInputError(
            f"--out {out} holds another run (seed {data.get('seed')}); pass --resume to continue "
            "it or --force to start anew"
        )


def _manifest(experiment: Experiment, seed: int, config: RunConfig) -> dict[str, Any]:
    return {
        "kind": experiment.kind,
        "mbn_version": code_identity()["version"],
        "code": code_identity(),
        "versions": versions(),
        "seed": seed,
        "config": config.to_dict(),
    }


def prepare(
    experiment: Experiment,
    rundir: RunDir,
    seed: int,
    config: RunConfig,
    *,
    resume: bool,
    force: bool,
    allow_other_code: bool = False,
) -> None:
    """Check the folder (:func:`check_out_dir`) and what the settings name
    (:meth:`RunConfig.check`: nothing is written or cleared for a config refused), then create
    the folder, or check that a run resumed was started with the same seed, config and code
    (:func:`mbn.provenance.code_difference`; other code is refused unless ``allow_other_code``,
    and then recorded in ``run.json``, ``other_code``)."""
    check_out_dir(rundir.root, experiment.kind, resume=resume, force=force)
    config.check()
    try:
        if force:
            rundir.clear()
        rundir.create()
    except OSError as exc:
        raise MbnInputError(f"--out {rundir.root}: cannot write ({exc.strerror or exc})") from None
    check_writable(rundir.manifest, "--out")
    mine = _manifest(experiment, seed, config)
    if resume:
        rundir.remove_temporary_files()
    if resume and rundir.manifest.exists():
        old = rundir.read_manifest()
        if old.get("seed") != seed:
            raise MbnInputError(
                f"{rundir.manifest}: the run was started with seed {old.get('seed')}, not {seed}; "
                "resume it with the same seed"
            )
        recorded = old.get("config")
        if isinstance(recorded, dict):
            # a section or key the run was recorded without ran as it did before it existed
            # (Settings.recorded_before): it resumes if that is what the config asks for now
            with contextlib.suppress(MbnInputError):  # unreadable: compared as it is
                recorded = experiment.config_from_dict(recorded, str(rundir.manifest)).to_dict()
        if recorded != mine["config"]:
            diff = first_difference(recorded, mine["config"])
            raise MbnInputError(
                f"{rundir.manifest}: the run was started with another config ({diff}); resume it "
                "with the same options and settings file"
            )
        _check_code(rundir, old, "resume", allow_other_code)
    else:
        write_json_atomic(rundir.manifest, mine)


def with_other_code(record: dict[str, Any], action: str) -> list[dict[str, Any]]:
    """The ``other_code`` entries of ``record`` (a ``run.json`` or ``sweep.json``) with one
    more: ``action`` (``resume``, ``continue``) went on with this code, not the one recorded
    (both identities)."""
    before = record.get("other_code")
    entries = list(before) if isinstance(before, list) else []
    return [*entries, {"action": action, "recorded": record.get("code"), "code": code_identity()}]


def _check_code(rundir: RunDir, manifest: dict[str, Any], action: str, allow: bool) -> None:
    """Refuse to ``action`` a run whose ``run.json`` records other code than this (one line),
    unless ``allow``; then record it there (``other_code``)."""
    diff = code_difference(manifest.get("code"))
    if diff is None:
        return
    if not allow:
        raise MbnInputError(
            f"{rundir.manifest}: {diff}; pass --allow-other-code to {action} it with this code "
            "(run.json records that you did)"
        )
    write_json_atomic(
        rundir.manifest, {**manifest, "other_code": with_other_code(manifest, action)}
    )


def _context(
    experiment: Experiment,
    rundir: RunDir,
    seed: int,
    config: RunConfig,
    stage: Stage,
    progress: Progress,
    log: Callable[[str], None] = print,
    workers: int = 1,
) -> StageContext:
    return StageContext(
        rundir=rundir,
        config=config,
        seed=seed,
        seeds=experiment.seeds(seed),
        run_key=jax.random.key(seed),
        name=stage.name,
        key_id=stage.key_id,
        needs=tuple(stage.needs),
        progress=progress,
        log=log,
        workers=workers,
    )


def run_stage(
    experiment: Experiment,
    rundir: RunDir,
    name: str,
    *,
    seed: int,
    config: RunConfig,
    progress: Progress | None = None,
    workers: int = 1,
) -> dict[str, Any]:
    """Run one stage against a run folder whose ``needs`` are done; writes ``stages/NAME.json``
    and returns the stage's data as written there (a JSON object; typed:
    ``rundir.read_result(StageClass)``)."""
    stage = experiment.registry[name]
    config.check()
    missing = [n for n in stage.needs if not rundir.stage_done(n)]
    if missing:
        raise MbnInputError(
            f"{rundir.root}: stage {name} needs {', '.join(missing)}, which have not run there"
        )
    rundir.create()
    with scope(config.get(RunSettings).precision):
        ctx = _context(
            experiment, rundir, seed, config, stage, progress or Progress(), print, workers
        )
        data = stage.to_json(stage.run(ctx))
    rundir.write_stage(name, data)
    return data


def maze_splits() -> dict[str, list[int]]:
    """The maze families' splits of generator seeds (first and last seed of each), which every
    ``results.json`` records (``docs/generalization.md``, "Splits")."""
    from mbn.world.mazes.families import SPLITS

    return {name: [r.start, r.stop - 1] for name, r in SPLITS.items()}


def mazes_looked_into() -> dict[str, list[int]]:
    """The test mazes somebody looked into, by family, which left the test split for validation
    (:data:`mbn.world.mazes.families.LOOKED_INTO`): every ``results.json`` records them."""
    from mbn.world.mazes.families import LOOKED_INTO

    return {name: list(seeds) for name, seeds in LOOKED_INTO.items()}


def collect_results(
    experiment: Experiment, rundir: RunDir, seed: int, config: RunConfig
) -> dict[str, Any]:
    """``results.json``: seeds, config, versions, per-stage metrics and the experiment's
    extras."""
    stages = {s.name: rundir.read_stage(s.name) for s in experiment.registry}
    results: dict[str, Any] = {
        "seed": seed,
        "seeds": experiment.seeds(seed),
        "quick": config.quick,
        "config": config.to_dict(),
        "versions": versions(),
        "code": code_identity(),
        "maze_splits": maze_splits(),
        "mazes_looked_into": mazes_looked_into(),
        "stages": {s.name: s.metrics(stages[s.name]) for s in experiment.registry},
    }
    if experiment.results is not None:
        results.update(experiment.results(rundir, stages, config))
    # what a sweep reads of every run (none where the experiment judges no test, makes no claim)
    results.setdefault("tests", {})
    results.setdefault("claims", [])
    return results


def run_experiment(
    experiment: Experiment,
    out: Path,
    *,
    seed: int,
    config: RunConfig,
    resume: bool = False,
    force: bool = False,
    progress: bool = False,
    log: Callable[[str], None] = print,
    stages: Sequence[str] | None = None,
    workers: int = 1,
    reuse: ReuseSource | None = None,
    allow_other_code: bool = False,
) -> dict[str, Any]:
    """Every stage not yet done (all, or those named in ``stages`` and what they need), then
    ``results.json`` and the report; returns the results (or, for a partial run, the data of
    the stages run). ``workers``: populations are evaluated in that many parts at once (threads;
    the results do not depend on it). ``reuse``: another run of the same seed whose stages this
    run takes where it can (:mod:`~mbn.experiments.pipeline.reuse`). ``allow_other_code``: resume
    a run, or take stages from one, made by other code (:mod:`mbn.provenance`); refused
    otherwise."""
    rundir = RunDir(Path(out))
    if reuse is not None:
        _check_reuse(experiment, rundir, seed, config, reuse, allow_other_code)
    prepare(
        experiment,
        rundir,
        seed,
        config,
        resume=resume,
        force=force,
        allow_other_code=allow_other_code,
    )
    if reuse is not None:
        taken = take_stages(
            experiment, rundir, seed, config, reuse, allow_other_code=allow_other_code
        )
        if taken:
            log(f"stages {', '.join(taken)}: taken from {reuse.root}")
        else:
            log(f"notice: no stage to take from {reuse.root}")
    timings = rundir.read_timings()
    steps = rundir.read_robot_steps()
    wanted = list(experiment.registry.names if stages is None else stages)
    for name in wanted:
        if name not in experiment.registry:
            raise MbnInputError(
                f"no stage {name!r} (the stages: {', '.join(experiment.registry.names)})"
            )
    # without bars (no terminal), plain lines through ``log`` while a stage runs long
    with Progress(progress, lines=log) as bars, scope(config.get(RunSettings).precision):
        overall = bars.task(f"mbn {experiment.name}", len(experiment.registry) + 1, quiet=True)
        ran: dict[str, Any] = {}
        for k, stage in enumerate(experiment.registry):
            bars.update(overall, completed=k, info=stage.name)
            if stages is not None and not _wanted(experiment.registry, stage.name, wanted):
                continue
            if rundir.stage_done(stage.name):
                missing = [f for f in stage.outputs if not (rundir.root / f).exists()]
                if not missing:
                    log(f"stage {stage.name}: done before, kept")
                    continue
                log(f"notice: stage {stage.name}: {missing[0]} is missing; running it again")
            t0, n0 = time.perf_counter(), robot_steps()
            bars.stage(stage.name)
            data = stage.run(_context(experiment, rundir, seed, config, stage, bars, log, workers))
            bars.stage(None)
            rundir.write_stage(stage.name, stage.to_json(data))
            timings[stage.name] = round(time.perf_counter() - t0, 2)
            steps[stage.name] = robot_steps() - n0
            rundir.write_timings(timings, steps)
            ran[stage.name] = data
            log(f"stage {stage.name}: {stage.summary(data)}")
        if stages is not None:
            return ran
        bars.update(overall, completed=len(experiment.registry), info="report")
        t0, n0 = time.perf_counter(), robot_steps()
        results = collect_results(experiment, rundir, seed, config)
        write_json_atomic(rundir.results, results)
        bars.stage("report")
        if experiment.report is not None:
            experiment.report(rundir)
        else:
            summaries = [
                (s.name, s.summary(s.from_json(rundir.read_stage(s.name), s.name)))
                for s in experiment.registry
            ]
            plain_report(
                rundir.root,
                f"mbn run {experiment.name}: seed {seed}",
                summaries,
                {**results, "seconds": timings},
            )
        bars.stage(None)
        timings["report"] = round(time.perf_counter() - t0, 2)
        steps["report"] = robot_steps() - n0
        rundir.write_timings(timings, steps)
        bars.update(overall, completed=len(experiment.registry) + 1, info="done")
    return results


def _check_reuse(
    experiment: Experiment,
    rundir: RunDir,
    seed: int,
    config: RunConfig,
    reuse: ReuseSource,
    allow_other_code: bool,
) -> None:
    """Refuse a ``--reuse`` source before the run's folder is made or its ``run.json`` written
    (a refused command must leave nothing that blocks the corrected one): the run's own folder,
    a run of another seed, one made with other settings for the stages both have, or by other
    code unless ``allow_other_code`` (:func:`~mbn.experiments.pipeline.reuse.check_agreement`,
    which :func:`~mbn.experiments.pipeline.reuse.take_stages` runs again as it takes them)."""
    if reuse.root.resolve() == rundir.root.resolve():
        raise MbnInputError(f"--reuse {reuse.root}: the run's own folder (use --resume)")
    check_agreement(experiment, reuse, seed, config, allow_other_code=allow_other_code)


def _wanted(registry: Registry, name: str, wanted: Sequence[str]) -> bool:
    """Whether ``name`` is wanted or needed (transitively) by a wanted stage."""
    todo, seen = list(wanted), set()
    while todo:
        n = todo.pop()
        if n in seen:
            continue
        seen.add(n)
        todo.extend(registry[n].needs)
    return name in seen


def replace_section(config: RunConfig, section: Settings) -> RunConfig:
    """``config`` with one section replaced."""
    return RunConfig(
        tuple(section if s.section == section.section else s for s in config.sections),
        origin=config.origin,
    )
