"""``mbn evaluate``: the summary of a controller file's trials, and one-line errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mbn.cli.main import main
from mbn.controllers import (
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    MBNControllerSpec,
    save_controller,
)
from mbn.networks.ctrnn import make_ctrnn
from mbn.networks.multiplier import load_default, save_multiplier
from mbn.networks.programmable import build_interpreter, differing_connections
from mbn.paper import published_lf, published_rf

KEYS = {
    "trials",
    "successes",
    "success_rate",
    "timed_out",
    "junctions",
    "correct_junctions",
    "mean_stall_fraction",
    "seconds",
}


@pytest.fixture(scope="session")
def files(tmp_path_factory):
    """A controller that drives straight ahead (speed neuron biased on, turn neuron neutral), an
    interpreter file and an MBN file."""
    folder = tmp_path_factory.mktemp("controllers")
    straight = make_ctrnn(np.zeros((3, 3)), np.zeros((3, 3)), 0.5, bias=[0.0, 0.0, 3.0])
    save_controller(folder / "straight.json", CTRNNControllerSpec(straight, behavior="right"))
    rf, lf = published_rf(), published_lf()
    interp = build_interpreter(rf, differing_connections(rf, lf), load_default())
    programs = {
        "right": np.asarray(interp.program_of(rf)).tolist(),
        "left": np.asarray(interp.program_of(lf)).tolist(),
    }
    im = InterpreterControllerSpec(interp, programs)
    save_controller(folder / "im.json", im)
    pm = make_ctrnn(np.zeros((3, 3)), np.zeros((3, 2)), 0.5)
    save_controller(folder / "mbn.json", MBNControllerSpec(im, pm, (0, 1, 2)))
    save_multiplier(folder / "mul.json", load_default())
    return folder


def run(capsys, *args):
    status = main(["evaluate", *map(str, args)])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_json_summary_of_a_ctrnn_controller(files, capsys):
    status, out, err = run(
        capsys,
        "--controller",
        files / "straight.json",
        "--maze",
        "fig4",
        "--behavior",
        "right",
        "--seconds",
        "10",
        "--repeats",
        "2",
        "--json",
    )
    assert status == 0, err
    result = json.loads(out)
    assert set(result) == KEYS
    assert result["trials"] == 10 * 2
    assert 0.0 <= result["success_rate"] <= 1.0
    assert result["success_rate"] == result["successes"] / result["trials"]
    # driving straight, robots cross junctions (and take the wrong exit at some)
    assert 0 < result["junctions"] <= 3 * result["trials"]
    assert 0 <= result["correct_junctions"] <= result["junctions"]
    assert 0.0 <= result["mean_stall_fraction"] <= 1.0
    assert result["seconds"] == 10.0
    assert 0 <= result["timed_out"] <= result["trials"] - result["successes"]


def test_any_rule_judges_the_same_trials_by_its_own_exits(files, capsys):
    """``--behavior`` takes any priority order: the same straight-driving trials judged by the
    right rule and by straight-right (named or written as its order) count the same junctions
    and differ in which were correct; a robot that only drives straight is right at every pass
    where straight is open for straight-right."""
    common = ("--controller", files / "straight.json", "--maze", "fig4", "--seconds", "20")
    results = {}
    for rule in ("right", "straight-right", "SRL", "s>r>l"):
        status, out, err = run(capsys, *common, "--behavior", rule, "--json")
        assert status == 0, err
        results[rule] = json.loads(out)
    assert results["straight-right"] == results["SRL"] == results["s>r>l"]
    a, b = results["right"], results["straight-right"]
    assert a["junctions"] == b["junctions"] > 0
    assert b["correct_junctions"] > a["correct_junctions"]
    status, out, err = run(capsys, *common, "--behavior", "SRL")
    assert "behavior straight-right" in out.splitlines()[0]


def test_the_default_time_limit_comes_from_the_maze_and_time_outs_are_counted(files, capsys):
    common = ("--controller", files / "straight.json", "--maze", "fig4", "--behavior", "right")
    status, out, err = run(capsys, *common, "--json")
    assert status == 0, err
    assert json.loads(out)["seconds"] == 90.0  # fig4: 1.5 x 17.4 m at 0.3 m/s, to 10 s
    # in 3 s a robot passes no junction and stalls nowhere: every trial timed out
    status, out, err = run(capsys, *common, "--seconds", "3", "--json")
    result = json.loads(out)
    assert result["timed_out"] == result["trials"] == 10 and result["junctions"] == 0
    status, out, err = run(capsys, *common, "--seconds", "3")
    lines = out.strip().splitlines()
    assert ", 3 s" in lines[0] and "from the maze" not in lines[0]
    assert "10 timed out (raise --seconds)" in lines[-1] and lines[-1].strip().startswith("total")
    assert all("1 timed out" in line for line in lines[1:-1])
    status, out, err = run(capsys, *common, "--seconds", "3", "--junctions", "1")
    assert "1 timed out" in out


def test_text_summary_of_an_mbn_on_tiles(files, capsys):
    status, out, err = run(
        capsys,
        "--controller",
        files / "mbn.json",
        "--maze",
        "fig4",
        "--behavior",
        "tiles",
        "--initial",
        "left",
        "--seconds",
        "2",
        "--allow-unstable",  # its interpreter is built from the published weights
    )
    assert status == 0, err
    lines = out.strip().splitlines()
    assert "mbn.controller.mbn" in lines[0] and "behavior tiles (initial left)" in lines[0]
    starts = [line for line in lines if line.strip().startswith("start")]
    assert len(starts) == 10 and all("/1 successes" in line for line in starts)
    assert lines[-1].strip().startswith("total: ") and "/10 successes" in lines[-1]


def _one_line_error(status, out, err, message):
    assert status == 2
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert message in lines[0], err


BASE = ("--maze", "fig4", "--behavior", "right", "--seconds", "1")


def test_wrong_kind_and_multiplier_files(files, capsys, tmp_path):
    wrong = tmp_path / "wrong.json"
    wrong.write_text(json.dumps({"kind": "mbn.controller.brain", "format_version": 1}))
    result = run(capsys, "--controller", wrong, *BASE)
    _one_line_error(*result, "not a controller file (kind 'mbn.controller.brain'")
    result = run(capsys, "--controller", files / "mul.json", *BASE)
    _one_line_error(*result, "is a multiplier, not a controller")
    result = run(capsys, "--controller", tmp_path / "none.json", *BASE)
    _one_line_error(*result, "none.json: cannot read")


def test_mazes_the_trials_cannot_use(files, capsys, tmp_path):
    bare = tmp_path / "bare.maze"
    bare.write_text("#######\n#.....#\n#######\n")
    straight = files / "straight.json"
    result = run(capsys, "--controller", straight, "--maze", bare, "--behavior", "right")
    _one_line_error(*result, "maze 'bare' has no start marks")
    result = run(capsys, "--controller", straight, "--maze", "cross_LSR", "--behavior", "tiles")
    _one_line_error(*result, "behavior 'tiles' needs tiles, and maze 'cross_LSR' has none")
    result = run(capsys, "--controller", straight, "--maze", "nowhere", "--behavior", "right")
    _one_line_error(*result, "unknown maze 'nowhere'")


def test_controllers_that_do_not_fit_the_behavior(files, capsys):
    tiles = ("--maze", "fig4", "--behavior", "tiles")
    result = run(capsys, "--controller", files / "straight.json", *tiles)
    _one_line_error(*result, "--behavior tiles needs a controller that reads the tiles")
    result = run(capsys, "--controller", files / "im.json", *tiles)
    _one_line_error(*result, "is an interpreter controller")
    result = run(capsys, "--controller", files / "mbn.json", *tiles, "--program", "right")
    _one_line_error(*result, "--program fixes the interpreter's program")
    result = run(capsys, "--controller", files / "straight.json", *BASE, "--program", "left")
    _one_line_error(*result, "--program is for interpreter and mbn controllers")


@pytest.mark.parametrize(
    ("flag", "value", "message"),
    [
        ("--repeats", "0", "argument --repeats: must be in [1, 10000], got 0"),
        ("--repeats", "1000000000", "argument --repeats: must be in [1, 10000]"),
        ("--seconds", "1e12", "argument --seconds: must be at most 36000 s, got 1e12"),
        ("--junctions", "40", "argument --junctions: must be in [1, 32], got 40"),
        ("--repeats", "two", "argument --repeats: 'two' is not an integer"),
        ("--seconds", "-1", "argument --seconds: must be a finite number > 0"),
        ("--seed", "-3", "argument --seed: must be in [0, 2**32)"),
        ("--behavior", "up", "argument --behavior: unknown rule 'up'"),
    ],
)
def test_bad_flags_exit_with_status_2(files, capsys, flag, value, message):
    args = ["--controller", files / "straight.json", "--maze", "fig4", "--behavior", "right"]
    with pytest.raises(SystemExit) as exc:
        run(capsys, *args, flag, value)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and message in err, err


def test_evaluation_leaves_the_files_alone(files, capsys):
    before = {p.name: p.read_bytes() for p in files.iterdir()}
    status, _, err = run(capsys, "--controller", files / "im.json", *BASE, "--program", "up")
    assert status == 2 and "no program 'up'" in err and len(err.strip().splitlines()) == 1
    run(capsys, "--controller", files / "mul.json", *BASE)
    assert {p.name: p.read_bytes() for p in files.iterdir()} == before


def test_a_controller_beyond_its_step_stability_limit_is_refused_unless_allowed(files, capsys):
    published = files / "published.json"
    save_controller(published, CTRNNControllerSpec(published_rf(), behavior="right"))
    base = ["--controller", published, *BASE]
    status, _, err = run(capsys, *base)
    assert status == 2 and len(err.strip().splitlines()) == 1
    assert "above the stability limit 0.771 ms" in err and "needs substeps >= 130" in err
    status, out, err = run(capsys, *base, "--allow-unstable", "--seconds", "2", "--json")
    assert status == 0, err
    assert json.loads(out)["trials"] == 10


def test_noise_is_seeded_recorded_and_its_errors_are_one_line(files, capsys):
    args = ("--controller", files / "straight.json", "--maze", "fig4", "--behavior", "right")
    args += ("--seconds", "10", "--repeats", "2", "--json")
    noise = "sonar_dropout=0.5,wheel_std=0.3,neuron_std=2"
    results = []
    for seed in (1, 1, 2):
        status, out, err = run(capsys, *args, "--noise", noise, "--seed", seed)
        assert status == 0, err
        results.append(json.loads(out))
    assert results[0] == results[1]  # the same seed, the same noise
    assert set(results[0]) == KEYS | {"noise"}
    assert results[0]["noise"]["sonar_dropout"] == 0.5 and results[0]["noise"]["camera_miss"] == 0
    status, out, _ = run(capsys, *args, "--seed", 1)
    clean = json.loads(out)
    # the noise moves the robots: their junction counts or stalls differ from the clean run's
    moved = lambda r: (r["junctions"], r["correct_junctions"], r["mean_stall_fraction"])  # noqa: E731
    assert moved(results[0]) != moved(clean) or moved(results[2]) != moved(clean)
    for bad, message in (
        ("sonar_dropout=2", "noise sonar_dropout: must be <= 1"),
        ("sonar=0.1", "noise sonar: unknown setting"),
        ("0.1", "expected KEY=VALUE"),
    ):
        status, _, err = run(capsys, *args, "--noise", bad)
        assert status == 2 and len(err.strip().splitlines()) == 1 and message in err, err
