"""The ``contest3`` stage of ``mbn run programs-vs-dynamics`` on the quick ``im_full`` run: the
three-behaviour task, the MBN's route (one new program, RF's and LF's kept, the interpreter
untouched) against a monolithic CTRNN, with the same budget and checks.

The tests that read the stage's run are slow (about 1.5 min on 2 cores each: left out of CI, run
with ``pytest -m slow``); the checks of its settings run in CI."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from mbn.controllers import (
    CTRNNControllerSpec,
    MBNControllerSpec,
    load_controller,
    read_controller_spec,
)
from mbn.errors import MbnInputError
from mbn.experiments.contest import PROGRAMS_VS_DYNAMICS
from mbn.experiments.pipeline import RunDir
from mbn.experiments.pipeline.runner import replace_section, run_stage
from mbn.experiments.stages.contest3 import TASK, Contest3Settings
from mbn.world.mazes.builtin import CROSSROAD_KINDS


@pytest.fixture(scope="session")
def contest3_run(im_full_run, tmp_path_factory):
    rundir, _, _ = im_full_run
    folder = tmp_path_factory.mktemp("contest3") / "run"
    shutil.copytree(rundir.root, folder)
    copy = RunDir(folder)
    config = PROGRAMS_VS_DYNAMICS.config(quick=True)
    # two checks (generations 0 and 2) are enough to test the loop; the contest's own tests
    # run more (this fixture lies on the test suite's critical path)
    config = replace_section(config, config["contest"].replace(generations=2))
    return copy, config, run_stage(PROGRAMS_VS_DYNAMICS, copy, "contest3", seed=3, config=config)


@pytest.mark.slow
def test_both_contenders_get_the_same_budget_and_checks(contest3_run):
    _, config, data = contest3_run
    s, c = config["contest3"], config["contest"]
    popsize = config["de"].popsize
    assert data["budget"] == popsize * (c.generations + 1)
    by = data["runs"][TASK]
    grown = [f"grown{n}" for n in s.grown_neurons]  # a run per size
    assert list(by) == ["programs", "monolithic", *grown]
    generations = [0, *range(c.check_every, c.generations + 1, c.check_every)]
    for who, d in by.items():
        n = len(d["checks"])
        assert [x["generation"] for x in d["checks"]] == generations[:n], who
        assert d["solved"] or n == len(generations), who
        first = next((x for x in d["checks"] if x["success"]), None)
        assert d["evaluations"] == (None if first is None else first["evaluations"])
        for suffix in ("", "_jitter", "_heldout"):
            assert f"{who}_three_behaviours{suffix}" in data["tests"]
    # what an evaluation costs each: one rule's crossroads against every rule's (and the
    # switch episodes), times the genome and its perturbed copies
    copies = 1 + config["followers"].perturbation_copies
    kinds = len(CROSSROAD_KINDS)
    assert by["programs"]["episodes_per_evaluation"] == kinds * c.variants * copies
    # every rule's tile crossroads, from rest and after each other tile, and the crossroads
    # without a tile (scored by right, the rule before any tile)
    per_rule = kinds * c.variants + 2 * kinds
    assert by["monolithic"]["episodes_per_evaluation"] == (3 * per_rule + kinds * c.variants) * (
        copies
    )
    assert by["monolithic"]["genes"] == s.neurons**2 + 3 + 3 * s.neurons + s.neurons
    assert by["programs"]["pm_evaluations"] == popsize * (s.pm_generations + 1)


@pytest.mark.slow
def test_the_mbn_keeps_rf_lf_and_the_interpreter_and_adds_one_program(contest3_run):
    rundir, _, data = contest3_run
    im = read_controller_spec(rundir.controller_file("im_full"))
    mbn = read_controller_spec(rundir.controller_file(f"contest_{TASK}_programs"))
    assert isinstance(mbn, MBNControllerSpec)
    assert mbn.tile_rules == ("right", "left", "straight-right")
    assert mbn.interpreter_spec.interpreter.digest() == data["sha256"]
    readout = np.asarray(mbn.readout)
    np.testing.assert_allclose(readout[:, 0], im.programs["right"], atol=1e-12)
    np.testing.assert_allclose(readout[:, 1], im.programs["left"], atol=1e-12)
    np.testing.assert_allclose(readout[:, 2], data["runs"][TASK]["programs"]["program"])
    assert np.all((readout >= 0) & (readout <= 1))


@pytest.mark.slow
def test_the_monolithic_file_reads_the_tiles_itself(contest3_run):
    rundir, config, _ = contest3_run
    path = rundir.controller_file(f"contest_{TASK}_monolithic")
    spec = read_controller_spec(path)
    assert isinstance(spec, CTRNNControllerSpec)
    n = config["contest3"].neurons
    assert spec.tile_rules == ("right", "left", "straight-right")
    assert np.asarray(spec.net.WE).shape == (n, 6)
    loaded = load_controller(path, check_stability=False)
    assert loaded.needs_camera and loaded.tile_rules == spec.tile_rules


@pytest.mark.slow
def test_the_grown_contender_starts_from_rf_and_grows_a_third_tile_input(contest3_run):
    rundir, config, data = contest3_run
    (n,) = config["contest3"].grown_neurons
    run = data["runs"][TASK][f"grown{n}"]
    assert run["grown_from"] == "rf" and run["neurons"] == n
    assert run["two_rule_evaluations"] == config["de"].popsize * (config["contest"].generations + 1)
    assert run["genes"] == n * n + 3 + 3 * n + n  # three tile inputs at the end
    first = rundir.load_checkpoint(f"contest_{TASK}_grown{n}_two").state
    assert np.asarray(first.population).shape[1] == n * n + 3 + 2 * n + n
    spec = read_controller_spec(rundir.controller_file(f"contest_{TASK}_grown{n}"))
    assert isinstance(spec, CTRNNControllerSpec) and np.asarray(spec.net.WE).shape == (n, 6)


@pytest.mark.slow
def test_the_baselines_run_the_mbn_s_own_programs_switched(contest3_run):
    from mbn.controllers import SwitchedControllerSpec
    from mbn.experiments.stages.programs import program_network

    rundir, _, data = contest3_run
    mbn = read_controller_spec(rundir.controller_file(f"contest_{TASK}_programs"))
    rf = read_controller_spec(rundir.controller_file("rf")).net
    interp = mbn.interpreter_spec.interpreter
    readout = np.asarray(mbn.readout)
    for mode, who in (("swap", "oracle"), ("gate", "gate")):
        spec = read_controller_spec(rundir.controller_file(f"contest_{TASK}_{who}"))
        assert isinstance(spec, SwitchedControllerSpec) and spec.mode == mode
        assert spec.tile_rules == mbn.tile_rules and spec.initial == "right"
        for k, rule in enumerate(mbn.tile_rules):  # each tile's network: its program decoded
            want = program_network(interp, rf, readout[:, k])
            np.testing.assert_allclose(
                np.asarray(spec.networks[rule].W), np.asarray(want.W), atol=1e-5
            )  # float32 weights decoded from a float64 program
        short = f"{who}_{TASK.replace('-', '_')}"
        for suffix in ("", "_jitter", "_heldout"):
            assert data["tests"][f"{short}{suffix}"]["trials"] > 0
        assert isinstance(data["baselines"][who]["final_success"], bool)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"tile_rules": ("right", "left")}, "three different rules"),
        ({"tile_rules": ("left", "right", "straight-left")}, "the first two are RF's and LF's"),
        ({"tile_rules": ("right", "left", "up")}, "unknown rule 'up'"),
        ({"contenders": ("programs", "mbn")}, "'mbn' is not one of programs, monolithic"),
        ({"neurons": 2}, "neurons"),
        ({"baselines": ("oracle", "switch")}, "'switch' is not one of oracle, gate"),
        ({"baselines": ("gate", "gate")}, "none listed twice"),
        ({"contenders": ("monolithic",)}, "built from the programs contender's programs"),
    ],
)
def test_settings_refuse_what_the_task_cannot_run(changes, message):
    with pytest.raises(MbnInputError, match=message):
        Contest3Settings(**changes)
