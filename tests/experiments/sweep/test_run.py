"""Scheduling and resume of a sweep, in this process (InlineExecutor) over a toy experiment run
by the real pipeline: finished seeds are skipped, interrupted ones resume from their stages, a
crash of one seed is reported while the others finish, a sweep with other settings is refused."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass
from typing import Any

import jax
import numpy as np
import pytest

from mbn.config import Settings, setting
from mbn.errors import MbnInputError
from mbn.experiments.pipeline import Experiment, Registry, RunDir, Stage, StageContext
from mbn.experiments.sweep.run import (
    InlineExecutor,
    SweepSettings,
    check_sweep_dir,
    run_seed,
    run_sweep,
    seed_dir,
    seed_state,
    task_env,
    thread_env,
)

CALLS: list[tuple[str, int]] = []
CRASH: dict[str, set[int]] = {"draw": set(), "total": set()}


@dataclass(frozen=True)
class DrawSettings(Settings):
    section = "draw"
    draws: int = setting(4, doc="numbers drawn", low=1)


class Draw(Stage):
    name, key_id, settings = "draw", 1, DrawSettings

    def run(self, ctx: StageContext) -> dict[str, Any]:
        CALLS.append((self.name, ctx.seed))
        if ctx.seed in CRASH["draw"]:
            raise RuntimeError(f"draw exploded for seed {ctx.seed}\nsecond line")
        x = np.asarray(jax.random.uniform(ctx.key, (ctx.settings.draws,)), dtype=float)
        return {"values": x.tolist()}


class Total(Stage):
    name, key_id, needs = "total", 2, ("draw",)

    def run(self, ctx: StageContext) -> dict[str, Any]:
        CALLS.append((self.name, ctx.seed))
        if ctx.seed in CRASH["total"]:
            raise KeyboardInterrupt if ctx.seed < 0 else RuntimeError("total: interrupted")
        return {"total": float(sum(ctx.read("draw")["values"]))}


def _report(rundir: RunDir) -> None:
    (rundir.root / "report.html").write_text("<html>toy</html>")


TOY = Experiment(
    name="toy",
    kind="mbn.toy",
    registry=Registry([Draw(), Total()]),
    results=lambda rundir, stages, config: {"tests": {}, "claims": []},
    report=_report,
)


@pytest.fixture(autouse=True)
def _fresh():
    CALLS.clear()
    CRASH["draw"].clear()
    CRASH["total"].clear()


def _sweep(out, seeds, config=None, reuse=None):
    settings = SweepSettings(tuple(seeds), config or TOY.config())
    return run_sweep(out, settings, lambda: InlineExecutor(run_seed), experiment=TOY, reuse=reuse)


def _files(folder):
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name != "timings.json"
    }


def test_every_seed_is_a_run_folder_and_a_rerun_skips_them(tmp_path):
    data = _sweep(tmp_path / "s", [0, 1, 2])
    assert {k: v["state"] for k, v in data["runs"].items()} == dict.fromkeys("012", "done")
    for s in (0, 1, 2):
        r = json.loads((seed_dir(tmp_path / "s", s) / "results.json").read_text())
        assert r["seed"] == s
    assert data["settings"]["seeds"] == [0, 1, 2]
    assert len(CALLS) == 6
    before = _files(tmp_path / "s" / "seed-1")
    CALLS.clear()

    def no_executor():
        raise AssertionError("a finished sweep started an executor")

    again = run_sweep(
        tmp_path / "s", SweepSettings((0, 1, 2), TOY.config()), no_executor, experiment=TOY
    )
    assert CALLS == [] and again["skipped"] == [0, 1, 2]
    assert _files(tmp_path / "s" / "seed-1") == before


def test_one_crashing_seed_is_reported_and_the_others_finish(tmp_path):
    CRASH["draw"].add(1)
    data = _sweep(tmp_path / "s", [0, 1, 2])
    runs = data["runs"]
    assert runs["0"]["state"] == runs["2"]["state"] == "done"
    assert runs["1"]["state"] == "failed"
    assert runs["1"]["error"] == "RuntimeError: draw exploded for seed 1"
    assert seed_state(tmp_path / "s", 1, TOY.config()) == "resume"
    CRASH["draw"].clear()
    CALLS.clear()
    data = _sweep(tmp_path / "s", [0, 1, 2])  # the same command again: only seed 1 runs
    assert CALLS == [("draw", 1), ("total", 1)]
    assert data["runs"]["1"]["state"] == "done" and data["runs"]["1"]["resumed"] is True


def test_a_seed_is_done_or_failed_never_both_when_its_worker_dies(tmp_path):
    """A worker that aborts (as Ray reports it: the task failed, no result) after its run was
    complete leaves a done seed, the failure a notice; one that aborts before, a failed seed.
    Either way sweep.json's state is what the folder says, which a rerun goes by."""
    crash = "WorkerCrashedError: The worker died unexpectedly while executing this task."

    def aborts(out, seed, config, resume, experiment=None):
        if seed == 0:
            run_seed(out, seed, config, resume, experiment)  # the run completes, then the abort
        return {"seed": seed, "state": "failed", "error": crash, "seconds": None}

    settings = SweepSettings((0, 1), TOY.config())
    data = run_sweep(tmp_path / "s", settings, lambda: InlineExecutor(aborts), experiment=TOY)
    done, failed = data["runs"]["0"], data["runs"]["1"]
    assert seed_state(tmp_path / "s", 0, TOY.config()) == "done" and done["state"] == "done"
    assert done["error"] is None
    assert done["notices"] == [
        f"notice: the run was complete when its worker ended abnormally ({crash}); kept"
    ]
    assert seed_state(tmp_path / "s", 1, TOY.config()) == "new"
    assert failed["state"] == "failed" and failed["error"] == crash
    # the same command again: the done seed is skipped, the failed one runs
    CALLS.clear()
    again = _sweep(tmp_path / "s", [0, 1])
    assert again["skipped"] == [0] and CALLS == [("draw", 1), ("total", 1)]


def test_an_interrupted_seed_resumes_and_ends_as_an_uninterrupted_one(tmp_path):
    CRASH["total"].add(2)
    _sweep(tmp_path / "a", [2, 3])
    assert seed_state(tmp_path / "a", 2, TOY.config()) == "resume"
    CRASH["total"].clear()
    CALLS.clear()
    _sweep(tmp_path / "a", [2, 3])
    assert CALLS == [("total", 2)]  # draw was done: resumed, not redone
    _sweep(tmp_path / "b", [2, 3])
    for s in (2, 3):
        assert _files(seed_dir(tmp_path / "a", s)) == _files(seed_dir(tmp_path / "b", s))


def test_a_sweep_with_other_settings_or_fewer_seeds_is_refused_and_left_alone(tmp_path):
    _sweep(tmp_path / "s", [0, 1, 2])
    before = _files(tmp_path / "s")
    with pytest.raises(
        MbnInputError, match=r"has seeds 0,2, which --seeds leaves out; a sweep may"
    ):
        _sweep(tmp_path / "s", [1, 3])
    other = TOY.config(quick=True)
    with pytest.raises(MbnInputError, match=r"other settings \(quick: false then, true now\)"):
        _sweep(tmp_path / "s", [0, 1, 2], other)
    with pytest.raises(MbnInputError, match="other settings"):
        _sweep(tmp_path / "s", [0, 1, 2, 3], other)  # more seeds do not excuse other settings
    assert _files(tmp_path / "s") == before


def test_a_sweep_gains_seeds_runs_only_the_new_ones_and_records_that_it_grew(tmp_path):
    """A sweep of seeds 0-1 continued with --seeds 0-2 (installments of a long sweep): seeds 0
    and 1 are kept as they were, seed 2 runs, and ``sweep.json`` says what the sweep held
    before."""
    _sweep(tmp_path / "s", [0, 1])
    kept = {s: _files(seed_dir(tmp_path / "s", s)) for s in (0, 1)}
    CALLS.clear()
    data = _sweep(tmp_path / "s", [0, 1, 2])
    assert {seed for _, seed in CALLS} == {2}
    assert data["settings"]["seeds"] == [0, 1, 2] and data["skipped"] == [0, 1]
    assert {k: r["state"] for k, r in data["runs"].items()} == dict.fromkeys("012", "done")
    assert [g["seeds_before"] for g in data["grown"]] == [[0, 1]]
    for s in (0, 1):
        assert _files(seed_dir(tmp_path / "s", s)) == kept[s]
    # the same command again changes nothing of that record; a sweep never grown has none
    assert [g["seeds_before"] for g in _sweep(tmp_path / "s", [0, 1, 2])["grown"]] == [[0, 1]]
    assert "grown" not in _sweep(tmp_path / "t", [0])


def test_out_that_is_a_file_or_holds_other_files_is_refused(tmp_path):
    settings = SweepSettings((0,), TOY.config())
    (tmp_path / "f").write_text("x")
    with pytest.raises(MbnInputError, match="is a file"):
        check_sweep_dir(tmp_path / "f", settings)
    with pytest.raises(MbnInputError, match="is a file"):
        check_sweep_dir(tmp_path / "f" / "sub", settings)
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "notes.txt").write_text("mine")
    with pytest.raises(MbnInputError, match="holds other files and no sweep"):
        check_sweep_dir(tmp_path / "d", settings)
    assert (tmp_path / "d" / "notes.txt").read_text() == "mine"


def test_auth_hint_only_where_token_authentication_can_be_why():
    from mbn.experiments.sweep.run import auth_hint

    hint = auth_hint("head:6379", {})
    assert "RAY_AUTH_MODE=token" in hint and "ray get-auth-token" in hint
    assert auth_hint(None, {}) == ""  # a local Ray started by the sweep itself
    assert auth_hint("auto", {}) == ""  # `auto` finds the local cluster and its token
    assert auth_hint("head:6379", {"RAY_AUTH_MODE": "token"}) == ""  # already set


def test_a_sweep_reusing_another_takes_each_seeds_stages_and_ends_the_same(tmp_path):
    _sweep(tmp_path / "a", [0, 1])
    CALLS.clear()
    settings = SweepSettings((0, 1, 2), TOY.config())
    data = _sweep(tmp_path / "b", [0, 1, 2], reuse=tmp_path / "a")
    assert CALLS == [("draw", 2), ("total", 2)]  # seed 2 has no run in a: it runs
    assert data["runs"]["0"]["notices"] == [f"stages draw, total: taken from {tmp_path}/a/seed-0"]
    for s in (0, 1):
        a, b = seed_dir(tmp_path / "a", s), seed_dir(tmp_path / "b", s)
        assert (
            json.loads((b / "results.json").read_text())["stages"]
            == json.loads((a / "results.json").read_text())["stages"]
        )
    with pytest.raises(MbnInputError, match=r"--reuse .*: not a sweep folder \(no sweep\.json\)$"):
        run_sweep(
            tmp_path / "c", settings, lambda: InlineExecutor(run_seed), reuse=tmp_path / "a/seed-0"
        )
    with pytest.raises(MbnInputError, match=r"--reuse .*b: the sweep's own folder$"):
        run_sweep(tmp_path / "b", settings, lambda: InlineExecutor(run_seed), reuse=tmp_path / "b")


@pytest.mark.parametrize("cpus", [1, 2, pytest.param(3, marks=pytest.mark.slow)])
def test_a_task_environment_lets_jax_start_and_compute(cpus):
    """XLA reads an ``XLA_FLAGS`` that does not start with ``--`` as a file name and aborts the
    process: the ``intra_op_parallelism_threads=N`` once written for N > 1 killed every task of
    ``--cpus-per-run 2``."""
    env = {**os.environ, **task_env(cpus, os.environ)}
    if "XLA_FLAGS" not in task_env(cpus, os.environ):
        env.pop("XLA_FLAGS", None)
    code = "import jax.numpy as jnp; print(float(jnp.arange(4.0).sum()))"
    proc = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip() == "6.0"
    assert all(flag.startswith("--") for flag in env.get("XLA_FLAGS", "").split())
    assert env["OMP_NUM_THREADS"] == env["MBN_FITNESS_WORKERS"] == str(cpus)


def test_thread_env_keeps_the_callers_xla_flags_in_front():
    own = {"XLA_FLAGS": "--xla_dump_to=/tmp/x"}
    one = "--xla_dump_to=/tmp/x --xla_cpu_multi_thread_eigen=false"
    assert thread_env(1, own)["XLA_FLAGS"] == one
    assert thread_env(2, own)["XLA_FLAGS"] == "--xla_dump_to=/tmp/x"
    assert "XLA_FLAGS" not in thread_env(2, {})


def test_a_reuse_sweep_with_other_shared_settings_is_refused_before_any_run(tmp_path):
    _sweep(tmp_path / "a", [0])
    CALLS.clear()
    more = TOY.config().to_dict()
    more["draw"]["draws"] = 5
    with pytest.raises(
        MbnInputError,
        match=r"sweep\.json: its runs were made with other settings \(draw\.draws: 4 then, 5 "
        r"now\); nothing can be taken from them$",
    ):
        _sweep(tmp_path / "b", [0], TOY.config_from_dict(more, "test"), reuse=tmp_path / "a")
    assert CALLS == [] and not (tmp_path / "b").exists()


def test_the_report_names_the_stages_each_seed_took(tmp_path):
    from mbn.experiments.sweep.report import finished_taken

    _sweep(tmp_path / "a", [0, 1])
    _sweep(tmp_path / "b", [0, 1, 2], reuse=tmp_path / "a")
    assert finished_taken(tmp_path / "b", [0, 1, 2]) == {0: ["draw", "total"], 1: ["draw", "total"]}


def test_a_sweep_made_by_other_code_is_continued_only_when_allowed_and_then_recorded(tmp_path):
    from mbn.provenance import code_identity, environment

    CRASH["total"].add(1)
    data = _sweep(tmp_path / "s", [0, 1])
    assert data["code"] == code_identity() and data["versions"] == environment()
    other = {"version": "0.1.0", "package_sha256": "0" * 64, "source": "package"}
    path = tmp_path / "s" / "sweep.json"
    path.write_text(json.dumps({**json.loads(path.read_text()), "code": other}))
    manifest = seed_dir(tmp_path / "s", 1) / "run.json"
    manifest.write_text(json.dumps({**json.loads(manifest.read_text()), "code": other}))
    CRASH["total"].clear()
    before = _files(tmp_path / "s")
    with pytest.raises(
        MbnInputError,
        match=r"sweep\.json: made by mbn 0\.1\.0 \(package 0000000000\); this is mbn .*; pass "
        r"--allow-other-code to continue it with this code \(sweep\.json records that you did\)$",
    ):
        _sweep(tmp_path / "s", [0, 1])
    assert _files(tmp_path / "s") == before
    settings = SweepSettings((0, 1), TOY.config())
    again = run_sweep(
        tmp_path / "s",
        settings,
        lambda: InlineExecutor(run_seed),
        experiment=TOY,
        allow_other_code=True,
    )
    assert again["runs"]["1"]["state"] == "done"
    assert again["code"] == other  # the code it was started with
    assert again["other_code"] == [
        {"action": "continue", "recorded": other, "code": code_identity()}
    ]
    resumed = json.loads(manifest.read_text())
    assert resumed["other_code"][0]["action"] == "resume"
