"""Inputs a reliability campaign found crashing, running without end or accepted in silence:
each now runs (where it is valid) or ends in one line and exit status 2 (``docs/bad-input.md``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mbn.cli.main import main
from mbn.controllers import CTRNNControllerSpec, controller_to_dict, save_controller
from mbn.networks.ctrnn import make_ctrnn

TRIAL = ("--maze", "fig4", "--behavior", "right")


def run(capsys, *args):
    status = main([str(a) for a in args])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def one_line_error(status, out, err, message):
    """Exit status 2, nothing on stdout, one line on stderr that holds ``message``."""
    assert status == 2, (out, err)
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("mbn") and "Traceback" not in err, err
    assert message in lines[0], err


def straight_spec(**changes) -> CTRNNControllerSpec:
    """A 3-neuron controller that drives straight ahead (speed neuron biased on)."""
    net = make_ctrnn(np.zeros((3, 3)), np.zeros((3, 3)), 0.5, bias=[0.0, 0.0, 3.0])
    return CTRNNControllerSpec(net, behavior="right", **changes)


def write_json(path: Path, data: dict) -> Path:
    path.write_text(json.dumps(data))
    return path


# -------------------------------------------------------------------------------------------
# 1. a large controller: the step-stability check in bounded memory
# -------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_a_1000_neuron_controller_is_checked_and_evaluated(tmp_path, capsys):
    """A 1000-neuron controller (weakly coupled: its 5 ms step is far within the stability
    limit) is checked and runs: exit 0 and the trials of fig4's 10 start marks (the check once
    stacked 1026 Jacobians of 1000 x 1000: a MemoryError)."""
    n = 1000
    rng = np.random.default_rng(0)
    net = make_ctrnn(
        rng.normal(0.0, 1.0, (n, n)) / np.sqrt(n),
        rng.normal(0.0, 1.0, (n, 3)),
        0.5,
        bias=np.r_[0.0, 0.0, 3.0, np.zeros(n - 3)],
    )
    path = tmp_path / "big.json"
    save_controller(path, CTRNNControllerSpec(net, behavior="right"))
    status, out, err = run(
        capsys, "evaluate", "--controller", path, *TRIAL, "--seconds", "1", "--json"
    )
    assert status == 0, err
    result = json.loads(out)
    assert result["trials"] == 10 and result["seconds"] == 1.0


# -------------------------------------------------------------------------------------------
# 2. the robot step and the length of a trial
# -------------------------------------------------------------------------------------------


@pytest.mark.parametrize("dt", [1e-300, 1e-7, 0.0009])
def test_a_robot_step_below_a_millisecond_is_refused(tmp_path, capsys, dt):
    """dt 1e-300 (an OverflowError in the rollout) and 1e-7 (past 120 s) are outside the
    documented range [0.001, 1] s, refused when the file is read."""
    data = controller_to_dict(straight_spec())
    path = write_json(tmp_path / "c.json", {**data, "dt": dt})
    result = run(capsys, "evaluate", "--controller", path, *TRIAL)
    one_line_error(*result, f"c.json: dt must be a number in [0.001, 1] s, got {dt!r}")


def test_the_shortest_documented_robot_step_runs(tmp_path, capsys):
    """dt 0.001 s, the bottom of the documented range, runs (a trial of 1 s: 1000 steps)."""
    path = tmp_path / "c.json"
    save_controller(path, straight_spec(dt=0.001, substeps=1))
    status, out, err = run(
        capsys, "evaluate", "--controller", path, *TRIAL, "--seconds", "1", "--json"
    )
    assert status == 0, err
    assert json.loads(out)["trials"] == 10


def test_a_trial_of_more_robot_steps_than_the_limit_is_refused(tmp_path, capsys):
    path = tmp_path / "c.json"
    save_controller(path, straight_spec(dt=0.001, substeps=1))
    result = run(capsys, "evaluate", "--controller", path, *TRIAL, "--seconds", "2000")
    one_line_error(
        *result,
        "c.json: a trial of 2000 s at its dt 0.001 s is 2,000,000 robot steps, above the limit "
        "of 1,000,000 a trial may take: raise its dt or lower --seconds",
    )


def test_a_trial_of_more_network_steps_than_the_limit_is_refused(tmp_path, capsys):
    path = tmp_path / "c.json"
    save_controller(path, straight_spec(substeps=10_000))
    result = run(capsys, "evaluate", "--controller", path, *TRIAL, "--seconds", "2000")
    one_line_error(
        *result,
        "c.json: a trial of 2000 s is 20,000 robot steps x 10,000 network steps = 200,000,000, "
        "above the limit of 100,000,000 network steps a trial may take: lower its substeps or "
        "--seconds",
    )


def test_the_step_limits_count_the_program_module_of_a_whole_mbn():
    """The whole MBN takes its interpreter's substeps and its program module's each robot
    step; its interpreter alone, only the interpreter's."""
    from mbn.controllers import InterpreterControllerSpec, MBNControllerSpec, make_controller
    from mbn.controllers.load import MAX_NETWORK_STEPS, check_trial_length
    from mbn.errors import MbnInputError
    from mbn.networks.multiplier import load_default
    from mbn.networks.programmable import build_interpreter, differing_connections
    from mbn.paper import published_lf, published_rf

    rf, lf = published_rf(), published_lf()
    interp = build_interpreter(rf, differing_connections(rf, lf), load_default())
    im = InterpreterControllerSpec(interp, {"right": np.asarray(interp.program_of(rf)).tolist()})
    pm = make_ctrnn(np.zeros((3, 3)), np.zeros((3, 2)), 0.5)
    spec = MBNControllerSpec(im, pm, (0, 1, 2), pm_substeps=10**6)
    # 1000 robot steps of 20 + 10^6 network steps: above the limit; the interpreter alone not
    whole = make_controller(spec, check_stability=False)
    with pytest.raises(MbnInputError, match=r"1,000 robot steps x 1,000,020 network steps"):
        check_trial_length(whole, 100.0, "mbn.json")
    alone = make_controller(spec, "right", check_stability=False)
    check_trial_length(alone, 100.0, "mbn.json")
    assert 1000 * 1_000_020 > MAX_NETWORK_STEPS >= 1000 * 20


# -------------------------------------------------------------------------------------------
# 3. pnn check --tau-ratio
# -------------------------------------------------------------------------------------------


def parser_error(capsys, *args) -> str:
    """The one line a flag the parser refuses gives (exit status 2)."""
    with pytest.raises(SystemExit) as exc:
        main([str(a) for a in args])
    assert exc.value.code == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert captured.out == "" and len(lines) == 1 and "Traceback" not in captured.err
    return lines[0]


@pytest.mark.parametrize("ratio", ["1e-300", "0.0005", "0", "20", "nan", "inf"])
def test_pnn_check_refuses_a_tau_ratio_outside_its_range(capsys, ratio):
    """1e-300 made a step of 5e-302 s and a 48-line TypeError: now one line naming the range."""
    line = parser_error(capsys, "pnn", "check", "--tau-ratio", ratio)
    assert line == (
        f"mbn pnn check: error: argument --tau-ratio: must be in [0.001, 10], got {ratio}"
    )


@pytest.mark.slow
def test_pnn_check_runs_at_the_smallest_tau_ratio(capsys):
    """0.001, the bottom of the range, runs (a step of 5e-5 s)."""
    status, out, err = run(
        capsys,
        "pnn",
        "check",
        "--tau-ratio",
        "0.001",
        "--sequences",
        "2",
        "--seconds",
        "1",
        "--json",
    )
    assert status == 0, err
    result = json.loads(out)
    assert result["num_sequences"] == 4
    assert result["exact"]["max_abs_output_diff"] < 1e-9


# -------------------------------------------------------------------------------------------
# 4. inputs once accepted in silence
# -------------------------------------------------------------------------------------------


@pytest.fixture(scope="session")
def interpreter_files(tmp_path_factory):
    """An interpreter file and an MBN file of the published RF/LF interpreter, each recording
    the sha256 of its weights in its metadata (as the runs write them)."""
    from mbn.controllers import InterpreterControllerSpec, MBNControllerSpec
    from mbn.networks.multiplier import load_default
    from mbn.networks.programmable import build_interpreter, differing_connections
    from mbn.paper import published_lf, published_rf

    folder = tmp_path_factory.mktemp("interpreters")
    rf, lf = published_rf(), published_lf()
    interp = build_interpreter(rf, differing_connections(rf, lf), load_default())
    programs = {
        "right": np.asarray(interp.program_of(rf)).tolist(),
        "left": np.asarray(interp.program_of(lf)).tolist(),
    }
    meta = {"sha256": interp.digest()}
    im = InterpreterControllerSpec(interp, programs, metadata=meta)
    save_controller(folder / "im.json", im)
    pm = make_ctrnn(np.zeros((3, 3)), np.zeros((3, 2)), 0.5)
    save_controller(folder / "mbn.json", MBNControllerSpec(im, pm, (0, 1, 2), metadata=meta))
    return folder


@pytest.mark.parametrize(
    ("noise", "key"),
    [
        ("sonar=0.1,sonar=0.2", "sonar"),
        ("sonar_std=0.1,wheel_std=0.1, sonar_std = 0.2", "sonar_std"),
    ],
)
def test_a_noise_key_given_twice_is_refused(tmp_path, capsys, noise, key):
    """The last value silently won: now one line naming the key."""
    path = tmp_path / "c.json"
    save_controller(path, straight_spec())
    line = parser_error(capsys, "evaluate", "--controller", path, *TRIAL, "--noise", noise)
    assert line == (
        f"mbn evaluate: error: argument --noise: {key} is given twice: give each key once"
    )


@pytest.mark.parametrize("name", ["", "  "])
def test_an_empty_program_name_is_refused(interpreter_files, capsys, name):
    """``--program ''`` ran the program named by --behavior in silence."""
    line = parser_error(
        capsys, "evaluate", "--controller", interpreter_files / "im.json", *TRIAL, "--program", name
    )
    assert line == (
        "mbn evaluate: error: argument --program: expected the name of a program stored in the "
        f"controller file, got {name!r}"
    )


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("0.5", "programs.left: expected numbers, got text '0.5' at index 1"),
        (True, "programs.left: expected numbers, got true at index 1"),
    ],
)
def test_program_values_written_as_text_are_refused(
    interpreter_files, tmp_path, capsys, value, message
):
    """A program value written as ``"0.5"`` was read as 0.5 and run, whichever program
    ``--program`` chose."""
    for name in ("im", "mbn"):
        data = json.loads((interpreter_files / f"{name}.json").read_text())
        data["programs"]["left"][1] = value
        path = write_json(tmp_path / f"{name}.json", data)
        for program in ("right", "left"):
            result = run(capsys, "evaluate", "--controller", path, *TRIAL, "--program", program)
            one_line_error(*result, f"mbn: error: {path}: {message}")


def test_program_values_given_to_program_are_refused_with_a_hint(interpreter_files, capsys):
    path = interpreter_files / "im.json"
    result = run(capsys, "evaluate", "--controller", path, *TRIAL, "--program", "0.5,0.5,0.5")
    one_line_error(
        *result,
        f"mbn: error: {path}: no program '0.5,0.5,0.5' (the file has: right, left); a program is "
        "chosen by its name, not written as values",
    )


def test_an_interpreter_whose_weights_changed_since_it_was_written_is_refused(
    interpreter_files, tmp_path, capsys
):
    """Files whose metadata records their interpreter's sha256 run while it holds, and are
    refused in one line naming the file once a weight is changed."""
    from mbn.io import read_json

    digest = read_json(interpreter_files / "im.json")["metadata"]["sha256"]
    for name in ("im", "mbn"):
        status, out, err = run(
            capsys,
            "evaluate",
            "--controller",
            interpreter_files / f"{name}.json",
            *TRIAL,
            "--program",
            "left",
            "--seconds",
            "1",
            "--json",
        )
        assert status == 0, err
        assert json.loads(out)["trials"] == 10
        data = json.loads((interpreter_files / f"{name}.json").read_text())
        data["interpreter"]["net"]["W"][1][2] += 0.5
        path = write_json(tmp_path / f"{name}.json", data)
        status, out, err = run(capsys, "evaluate", "--controller", path, *TRIAL)
        one_line_error(status, out, err, f"mbn: error: {path}: the interpreter's sha256 is ")
        assert err.strip().endswith(
            f"…, not the {digest[:12]}… its metadata records: its weights were changed since the "
            "file was written"
        ), err
