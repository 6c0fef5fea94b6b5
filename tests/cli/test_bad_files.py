"""Files that cannot be written or read: one line naming the path and the reason, exit status 2,
checked before any long work, nothing written."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mbn.cli.main import main


def _one_line(capsys, *words: str) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("mbn: error: "), err
    assert "Traceback" not in err
    for w in words:
        assert w in err, err
    return err


def _pairs(tmp_path: Path) -> Path:
    path = tmp_path / "pairs.csv"
    path.write_text("x1,x2\n0.5,0.5\n")
    return path


def _poses(tmp_path: Path) -> Path:
    path = tmp_path / "poses.csv"
    path.write_text("x,y,theta\n0.5,0.5,0\n")
    return path


COMMANDS = {
    "mul train": lambda tmp, out: (
        ["mul", "train", "--iterations", "1", "--restarts", "2", "--out", out]
    ),
    "mul eval": lambda tmp, out: ["mul", "eval", "--pairs", str(_pairs(tmp)), "--out", out],
    "mul report": lambda tmp, out: ["mul", "report", "--out", out],
    "show-maze": lambda tmp, out: ["show-maze", "cross_L", "--out", out],
    "sonar": lambda tmp, out: (
        ["sonar", "--maze", "stage_arena", "--poses", str(_poses(tmp)), "--out", out]
    ),
    "drive": lambda tmp, out: (
        ["drive", "--start", "0,0,0", "--cmd", "0,0", "--seconds", "1", "--out", out]
    ),
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize(
    ("where", "words"),
    [
        ("folder", ["is a folder, not a file"]),
        ("missing", ["does not exist"]),
        ("proc", ["/proc/", "cannot write"]),
    ],
)
def test_an_output_that_cannot_be_written_is_one_line_before_any_work(
    tmp_path, capsys, monkeypatch, command, where, words
):
    import mbn.networks.multiplier_train as train

    def no_training(*args, **kwargs):
        raise AssertionError("trained before checking --out")

    monkeypatch.setattr(train, "train_stages", no_training)
    out = {
        "folder": str(tmp_path),
        "missing": str(tmp_path / "no" / "such" / "out.x"),
        "proc": "/proc/mbn-out.x",
    }[where]
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(COMMANDS[command](tmp_path, out)) == 2
    _one_line(capsys, out, *words)
    after = sorted(p.name for p in tmp_path.iterdir() if p.suffix != ".csv")
    assert after == [p for p in before if not p.endswith(".csv")]


def test_reproduce_into_a_folder_that_cannot_be_made_is_one_line(capsys):
    assert main(["reproduce", "--quick", "--out", "/proc/mbn-run"]) == 2
    _one_line(capsys, "--out /proc/mbn-run", "cannot write")


@pytest.mark.parametrize(
    ("flag", "make"),
    [
        ("--controller", lambda p: p.write_bytes(b'{"kind": "mbn.controller.ctrnn\xff"}')),
        ("--params", lambda p: p.write_bytes(b'{"kind": "\xfe"}')),
    ],
)
def test_a_file_that_is_not_utf8_is_one_line(tmp_path, capsys, flag, make):
    path = tmp_path / "f.json"
    make(path)
    if flag == "--controller":
        argv = ["evaluate", "--controller", str(path), "--maze", "fig4", "--behavior", "right"]
    else:
        argv = ["mul", "report", "--params", str(path), "--out", str(tmp_path / "m.png")]
    assert main(argv) == 2
    _one_line(capsys, str(path), "not UTF-8")


@pytest.mark.parametrize("command", ["mul eval", "sonar"])
def test_a_csv_that_is_not_utf8_or_has_a_huge_field_is_one_line(tmp_path, capsys, command):
    header = "x1,x2" if command == "mul eval" else "x,y,theta"
    bad = tmp_path / "bad.csv"
    bad.write_bytes(header.encode() + b"\n0.5,\xff\n")
    huge = tmp_path / "huge.csv"
    huge.write_text(header + "\n" + "1" * 200_000 + ",1,1\n")
    for path, words in ((bad, ["bad.csv:2", "not UTF-8"]), (huge, ["huge.csv:2", "field larger"])):
        if command == "mul eval":
            argv = ["mul", "eval", "--pairs", str(path), "--out", str(tmp_path / "o.csv")]
        else:
            argv = ["sonar", "--maze", "stage_arena", "--poses", str(path)]
            argv += ["--out", str(tmp_path / "o.csv")]
        assert main(argv) == 2
        err = _one_line(capsys, *words)
        assert len(err) < 300
    assert not (tmp_path / "o.csv").exists()


def test_json_nested_100000_deep_is_one_line(tmp_path, capsys):
    path = tmp_path / "deep.json"
    path.write_text("[" * 100_000 + "]" * 100_000)
    argv = ["evaluate", "--controller", str(path), "--maze", "fig4", "--behavior", "right"]
    assert main(argv) == 2
    _one_line(capsys, "deep.json", "nested too deeply")


def test_a_run_manifest_that_is_a_list_is_one_line(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text(json.dumps([1, 2]))
    assert main(["reproduce", "--quick", "--out", str(run), "--resume"]) == 2
    _one_line(capsys, "run.json", "expected an object")


def test_a_world_with_thousands_of_nested_models_is_one_line(tmp_path, capsys):
    path = tmp_path / "nested.world"
    path.write_text("define m model ( )\n" + "m (\n" * 5000 + ")\n" * 5000)
    assert main(["show-maze", str(path), "--out", str(tmp_path / "n.png")]) == 2
    _one_line(capsys, "nested.world:66", "nested more than 64 deep")


@pytest.mark.parametrize(
    ("metrics", "words"),
    [
        ([1, 2], "metrics: expected an object, got list"),
        ({"training": [1]}, "metrics.training: expected an object, got list"),
        ({"training": {"seed": "7"}}, "metrics.training.seed: expected an integer, got '7'"),
        ({"training": {"seed": -1}}, "metrics.training.seed must be in [0, 2**32)"),
    ],
)
def test_a_multiplier_file_with_metrics_of_the_wrong_types_is_one_line(
    tmp_path, capsys, metrics, words
):
    from mbn.networks.multiplier import load_default, multiplier_to_dict

    path = tmp_path / "mul.json"
    data = multiplier_to_dict(load_default(3))
    data["metrics"] = metrics
    path.write_text(json.dumps(data))
    assert main(["mul", "report", "--params", str(path), "--out", str(tmp_path / "m.png")]) == 2
    _one_line(capsys, "mul.json", words)
    assert not (tmp_path / "m.png").exists()


def test_a_json_integer_of_thousands_of_digits_is_one_line(tmp_path, capsys):
    path = tmp_path / "big.json"
    path.write_text('{"kind": "mbn.controller.ctrnn", "format_version": ' + "9" * 5000 + "}")
    argv = ["evaluate", "--controller", str(path), "--maze", "fig4", "--behavior", "right"]
    assert main(argv) == 2
    _one_line(capsys, "big.json", "invalid JSON (Exceeds the limit")


def test_only_mbn_warnings_reach_stderr_as_one_line(monkeypatch, capsys):
    import argparse
    import warnings

    import numpy as np

    import mbn.cli.main as cli
    from mbn.errors import MbnWarning

    def noisy(args: argparse.Namespace) -> int:
        np.log(np.zeros(1))  # numpy: divide by zero
        warnings.warn("a JAX-style note", UserWarning, stacklevel=1)
        warnings.warn("the step is close to its limit", MbnWarning, stacklevel=1)
        return 0

    parser = cli.build_parser()
    monkeypatch.setattr(
        cli,
        "build_parser",
        lambda: _Fixed(parser, argparse.Namespace(func=noisy, precision="float32")),
    )
    assert cli.main(["mazes"]) == 0
    assert capsys.readouterr().err.strip() == "mbn: warning: the step is close to its limit"


class _Fixed:
    def __init__(self, parser, namespace):
        self.parser, self.namespace = parser, namespace

    def parse_args(self, argv):
        return self.namespace


@pytest.fixture
def small_disk(tmp_path):
    """A 64 kB file system (tmpfs), full but for a few kB, and a read-only one; skipped where
    file systems cannot be mounted (not root, or no mount)."""
    import shutil
    import subprocess

    if shutil.which("mount") is None:
        pytest.skip("no mount command")
    full, ro = tmp_path / "full", tmp_path / "ro"
    full.mkdir()
    ro.mkdir()
    mounted = []
    try:
        for where, options in ((full, "size=64k"), (ro, "size=64k,ro")):
            done = subprocess.run(
                ["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(where)],
                capture_output=True,
            )
            if done.returncode != 0:
                pytest.skip("cannot mount a tmpfs here")
            mounted.append(where)
        (full / "filler").write_bytes(b"\0" * 60_000)
        yield full, ro
    finally:
        for where in mounted:
            subprocess.run(["umount", str(where)], capture_output=True)


def test_a_full_disk_and_a_read_only_folder_are_one_line_each(tmp_path, capsys, small_disk):
    full, ro = small_disk
    pairs = tmp_path / "pairs.csv"
    pairs.write_text("x1,x2\n" + "0.25,0.5\n" * 20_000)
    assert main(["mul", "eval", "--pairs", str(pairs), "--out", str(full / "o.csv")]) == 2
    _one_line(capsys, str(full / "o.csv"), "No space left on device")
    assert sorted(p.name for p in full.iterdir()) == ["filler"]  # no half-written or temp file
    assert main(["mul", "eval", "--pairs", str(pairs), "--out", str(ro / "o.csv")]) == 2
    _one_line(capsys, str(ro / "o.csv"), "Read-only file system")
    assert main(["reproduce", "--quick", "--out", str(ro / "run")]) == 2
    _one_line(capsys, str(ro / "run"), "cannot write")
