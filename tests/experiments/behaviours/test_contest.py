"""The ``contest`` stage of ``mbn run programs-vs-dynamics`` on the quick ``im_full`` run: the
same budget for every contender, evaluations to success read off the checks, the neighbour
starting at RF, the interpreter untouched, the report, and a run interrupted mid-contest
resuming to the same data.

The tests that read the stage's run are slow (about 1.5 min on 2 cores each: left out of CI, run
with ``pytest -m slow``); the checks of its settings run in CI."""

from __future__ import annotations

import json
import shutil

import jax
import numpy as np
import pytest

from mbn.controllers import (
    CTRNNControllerSpec,
    make_controller,
    read_controller_spec,
    step_beyond_limit,
)
from mbn.errors import MbnInputError
from mbn.experiments.contest import PROGRAMS_VS_DYNAMICS
from mbn.experiments.pipeline import RunDir
from mbn.experiments.pipeline.runner import replace_section, run_stage
from mbn.experiments.stages import contest as contest_module
from mbn.experiments.stages.contest import (
    CONTENDERS,
    ContestSettings,
    neighbour_population,
)
from mbn.networks.ctrnn import CTRNN
from mbn.paper import published_rf

RULE = "straight-right"


def _config():
    config = PROGRAMS_VS_DYNAMICS.config(quick=True)
    section = config["contest"].replace(rules=(RULE,))
    return replace_section(config, section)


def _run(rundir: RunDir):
    return run_stage(PROGRAMS_VS_DYNAMICS, rundir, "contest", seed=3, config=_config())


@pytest.fixture(scope="session")
def contest_run(im_full_run, tmp_path_factory):
    rundir, _, _ = im_full_run
    folder = tmp_path_factory.mktemp("contest") / "run"
    shutil.copytree(rundir.root, folder)
    copy = RunDir(folder)
    return copy, _run(copy)


@pytest.mark.slow
def test_every_contender_gets_the_same_budget_and_checks(contest_run):
    _, data = contest_run
    s = _config()["contest"]
    popsize = _config()["de"].popsize
    assert data["budget"] == popsize * (s.generations + 1)
    by = data["runs"][RULE]
    assert list(by) == list(CONTENDERS)
    generations = [0, *range(s.check_every, s.generations + 1, s.check_every)]
    assert s.stop_when_solved
    for who, d in by.items():
        # checked every check_every generations until the first success (then it stops)
        n = len(d["checks"])
        assert [c["generation"] for c in d["checks"]] == generations[:n], who
        assert d["solved"] or n == len(generations), f"{who}: unsolved runs spend the budget"
        assert all(not c["success"] for c in d["checks"][:-1]), f"{who}: ran on after success"
        # DE stopped at the last check: its history holds the generations up to it
        assert len(d["history"]["best"]) - 1 == d["checks"][-1]["generation"], who
        assert [c["evaluations"] for c in d["checks"]] == [popsize * (g + 1) for g in generations]
        fitness = [c["best_fitness"] for c in d["checks"]]
        assert fitness == sorted(fitness), f"{who}: DE's best never gets worse"
        # evaluations to success: the first check that passed, or censored
        first = next((c for c in d["checks"] if c["success"]), None)
        assert d["solved"] == (first is not None)
        assert d["evaluations"] == (None if first is None else first["evaluations"])
        for c in d["checks"]:
            k, n = c["marks"]
            if k < n:  # a failed mark fails the check: no jittered trials run
                assert c["jitter"] is None and not c["success"]
            else:
                j, m = c["jitter"]
                assert c["success"] == (j / m >= s.jitter_target)
    assert by["programs"]["genes"] == len(read_im_connections(contest_run[0]))
    assert by["scratch"]["genes"] == by["neighbour"]["genes"] == 12


def read_im_connections(rundir: RunDir):
    return read_controller_spec(rundir.controller_file("im_full")).interpreter.connections


@pytest.mark.slow
def test_final_tests_and_the_programs_through_the_interpreter(contest_run):
    rundir, data = contest_run
    short = RULE.replace("-", "_")
    for who in CONTENDERS:
        for suffix in ("", "_jitter", "_heldout"):
            assert data["tests"][f"{who}_{short}{suffix}"]["trials"] > 0
        spec = read_controller_spec(rundir.controller_file(f"contest_{RULE}_{who}"))
        assert spec.behavior == RULE
    for suffix in ("", "_jitter", "_heldout"):
        a = data["agreement"][f"im_programs_{short}{suffix}"]
        assert a["trials"] == data["tests"][f"im_programs_{short}{suffix}"]["trials"]
    assert data["sha256"] == rundir.read_stage("im_full")["sha256"]


@pytest.mark.slow
def test_a_final_network_beyond_its_step_stability_limit_is_tested_and_recorded(contest_run):
    # The checks run every candidate at the robot's network step, stable or not; the final
    # tests run the final best the same way (a network from scratch once left the worst-case
    # limit, and its tests were refused) and the record says whether it is beyond the limit.
    _, data = contest_run
    for who, record in data["runs"][RULE].items():
        spec = CTRNNControllerSpec(CTRNN.from_dict(record["network"]), behavior=RULE)
        where = f"contest_{RULE}_{who}"
        assert record["step_beyond_stability_limit"] == step_beyond_limit(spec, where)
    beyond = CTRNNControllerSpec(published_rf(), behavior="right")
    message = step_beyond_limit(beyond, "contest_right_scratch")
    assert message is not None
    assert message.startswith("contest_right_scratch: its network's step 5 ms")
    assert "needs substeps >= 130" in message
    loaded = make_controller(beyond, None, check_stability=False)
    assert loaded.dt == pytest.approx(0.1)
    with pytest.raises(MbnInputError, match="above the stability limit"):
        make_controller(beyond, None)


@pytest.mark.slow
def test_program_search_is_checked_through_the_interpreter(contest_run):
    """By default (``[contest] program_checks = "interpreter"``) program search's best so far is
    checked as the fixed interpreter runs it: the last check's start marks are those of the
    interpreter with that program."""
    import dataclasses

    from mbn.controllers import make_controller
    from mbn.experiments.trials import TrialSpec, run_loaded_trials, summary
    from mbn.world.mazes.load import load_maze

    rundir, data = contest_run
    config = _config()
    assert config["contest"].program_checks == "interpreter"
    assert data["program_checks"] == "interpreter"
    log = rundir.checkpoint_file(f"contest_{RULE}_programs").with_suffix(".checks.json")
    last = json.loads(log.read_text())[-1]
    spec = read_controller_spec(rundir.controller_file("im_full"))
    program = np.clip(np.asarray(last["best_genome"], float), 0.0, 1.0)
    im = dataclasses.replace(spec, programs={RULE: program.tolist()})
    loaded = make_controller(im, RULE, where="test")
    marks = TrialSpec(behavior=RULE, initial="right", seconds=config["tests"].seconds)
    got, _, _ = run_loaded_trials(load_maze(config["tests3"].maze), marks, loaded)
    assert [summary(got)["successes"], summary(got)["trials"]] == last["marks"]


def test_the_neighbour_starts_at_rf_and_its_copies_around_it():
    genes = np.linspace(-19.0, 19.0, 12)
    pop = neighbour_population(genes, jax.random.PRNGKey(0), 50, 2.0, 20.0)
    assert pop.shape == (50, 12)
    np.testing.assert_array_equal(pop[0], genes)
    assert np.all(np.abs(pop) <= 20.0)
    # away from the bounds, the spread is sigma (50 copies: within 35 %)
    spread = np.std(pop[1:, 3:9] - genes[3:9], axis=0)
    np.testing.assert_allclose(spread, 2.0, rtol=0.35)
    again = neighbour_population(genes, jax.random.PRNGKey(0), 50, 2.0, 20.0)
    np.testing.assert_array_equal(pop, again)


def test_settings_refuse_unknown_contenders_and_repeated_rules():
    with pytest.raises(MbnInputError, match="program_checks"):
        ContestSettings(program_checks="both")
    with pytest.raises(MbnInputError, match=r"contest\.contenders: 'lamarck' is not one of"):
        ContestSettings(contenders=("programs", "lamarck"))
    with pytest.raises(MbnInputError, match=r"contest\.rules"):
        ContestSettings(rules=("straight-right", "SR"))


@pytest.mark.slow
def test_the_report_draws_the_checks(contest_run, tmp_path):
    from mbn.experiments.contest.report import write_report

    rundir, data = contest_run
    folder = tmp_path / "run"
    shutil.copytree(rundir.root, folder)
    copy = RunDir(folder)
    (folder / "results.json").write_text(
        json.dumps({"seed": 3, "stages": ["contest"], "tests": data["tests"]})
    )
    write_report(copy)
    md = (folder / "report.md").read_text()
    assert "figures/contest.png" in md and (folder / "figures" / "contest.png").stat().st_size
    for who in CONTENDERS:
        assert f"| {RULE} | {who} |" in md


@pytest.mark.slow
def test_a_contest_interrupted_mid_run_resumes_to_the_same_data(im_full_run, tmp_path, monkeypatch):
    rundir, _, _ = im_full_run
    folders = []
    for name in ("whole", "cut"):
        shutil.copytree(rundir.root, tmp_path / name)
        folders.append(RunDir(tmp_path / name))
    whole = _run(folders[0])
    calls = {"n": 0}
    check = contest_module._check

    def dies(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 4:  # the second contender's second check
            raise KeyboardInterrupt
        return check(*args, **kwargs)

    monkeypatch.setattr(contest_module, "_check", dies)
    with pytest.raises(KeyboardInterrupt):
        _run(folders[1])
    monkeypatch.setattr(contest_module, "_check", check)
    again = _run(folders[1])
    assert json.dumps(again, sort_keys=True) == json.dumps(whole, sort_keys=True)


@pytest.mark.slow
def test_the_sweep_finds_every_test_it_tabulates(contest_run):
    from mbn.experiments.contest.sweep import CONTEST_SPEC

    _, data = contest_run
    mine = [t for t in CONTEST_SPEC.tests if "straight_right" in t]
    assert len(mine) == 18 and all(t in data["tests"] for t in mine)


@pytest.mark.slow
def test_mbn_run_programs_vs_dynamics_quick_end_to_end_and_over_runs(tmp_path):
    import subprocess
    import sys

    from mbn.experiments.contest.over_runs import contest_over_runs

    out = tmp_path / "pvd"
    cmd = [sys.executable, "-m", "mbn", "run", "programs-vs-dynamics", "--quick", "--quiet"]
    proc = subprocess.run([*cmd, "--out", str(out)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    results = json.loads((out / "results.json").read_text())
    tasks = {"straight-right", "straight-left", "three-behaviours"}
    assert set(results["contest"]) == tasks
    for rule in results["contest"]:
        for who in results["contest"][rule]:
            assert (out / "figures" / f"contest_{rule}_{who}.png").stat().st_size > 0
    assert set(results["contest"]["three-behaviours"]) == {"programs", "monolithic"}
    html = (out / "report.html").read_text()
    assert "Donnarumma et al. 2016" in html and "data:image/png;base64" in html
    assert "The three-behaviour task" in html
    stats, secs, images = contest_over_runs(out, {0: results})
    assert set(stats["rules"]) == tasks and secs and images
    assert set(stats["rules"]["three-behaviours"]["versus"]) == {"monolithic"}
