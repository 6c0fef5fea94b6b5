"""End-to-end tests of the `mbn` command line (run in-process and as a subprocess)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from mbn.cli.main import main


def run_cli(capsys, *args):
    status = main(list(args))
    out = capsys.readouterr()
    return status, out.out, out.err


def test_help_lists_the_commands_with_examples(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    for word in ("mul train", "mul eval", "mul report", "pnn check"):
        assert word in text


def test_python_dash_m_mbn_runs():
    result = subprocess.run(
        [sys.executable, "-m", "mbn", "--version"], capture_output=True, text=True, check=False
    )
    assert result.returncode == 0
    assert result.stdout.startswith("mbn ")


def test_mul_eval_multiplies_the_pairs_of_a_csv(tmp_path, capsys):
    pairs = tmp_path / "in.csv"
    pairs.write_text("x1,x2\n0.5,0.5\n0.9,0.2\n0.3,0.7\n")
    out = tmp_path / "out.csv"
    status, _, err = run_cli(capsys, "mul", "eval", "--pairs", str(pairs), "--out", str(out))
    assert status == 0, err
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    assert out.read_text().splitlines()[0] == "x1,x2,output"
    np.testing.assert_allclose(table[:, 2], table[:, 0] * table[:, 1], atol=0.05)


def test_mul_report_writes_a_png_and_prints_metrics(tmp_path, capsys):
    png = tmp_path / "err.png"
    status, out, err = run_cli(capsys, "mul", "report", "--out", str(png), "--json")
    assert status == 0, err
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    metrics = json.loads(out)
    assert 0.0 <= metrics["fraction_within_5pct"] <= 1.0
    assert metrics["num_validation_pairs"] == 100
    assert metrics["fixed_point"]["passed"]


def test_mul_train_writes_parameters_and_metrics(tmp_path, capsys):
    out = tmp_path / "mul.json"
    status, text, err = run_cli(
        capsys,
        "mul",
        "train",
        "--restarts",
        "4",
        "--iterations",
        "50",
        "--seed",
        "7",
        "--out",
        str(out),
        "--quiet",
    )
    assert status == 0, err
    data = json.loads(out.read_text())
    assert data["kind"] == "mbn.multiplier"
    assert data["metrics"]["training"]["seed"] == 7
    assert data["metrics"]["training"]["stages"][0]["num_restarts"] == 4
    assert "validation pairs within 5 %" in text
    # and the file is usable by the other commands
    status, _, err = run_cli(
        capsys, "mul", "report", "--params", str(out), "--out", str(tmp_path / "m.png")
    )
    assert status == 0, err


def test_pnn_check_json_has_the_documented_fields(capsys):
    status, out, err = run_cli(
        capsys, "pnn", "check", "--json", "--sequences", "10", "--seconds", "5"
    )
    assert status == 0, err
    result = json.loads(out)
    assert set(result) == {"exact", "trained", "num_sequences"}
    assert result["num_sequences"] == 20
    assert result["exact"]["max_abs_output_diff"] <= 1e-6
    assert {"median_max_abs_output_diff", "p95_max_abs_output_diff"} <= set(result["trained"])


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="trained-multiplier target not met (docs/programmable.md)")
def test_pnn_check_meets_the_targets_at_full_size(capsys):
    status, out, err = run_cli(capsys, "pnn", "check", "--json")
    assert status == 0, err
    result = json.loads(out)
    assert result["num_sequences"] == 400
    assert result["exact"]["max_abs_output_diff"] <= 1e-6
    assert result["trained"]["median_max_abs_output_diff"] <= 0.02
    assert result["trained"]["p95_max_abs_output_diff"] <= 0.1


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("x1,y\n0.1,0.2\n", r"in.csv:1: missing column\(s\) x2"),
        ("x1,x2\n0.1,0.2\n0.3,abc\n", r"in.csv:3: column x2: 'abc' is not a number"),
        ("x1,x2\n0.1,0.2\n0.3\n", r"in.csv:3: expected 2 fields, got 1"),
        ("x1,x2\n0.1,1.5\n", r"in.csv: data row 1: x1, x2 must be in \[0, 1\]"),
        ("", r"in.csv:1: empty file"),
    ],
)
def test_bad_csv_gives_one_line_and_status_2(tmp_path, capsys, content, message):
    import re

    pairs = tmp_path / "in.csv"
    pairs.write_text(content)
    out = tmp_path / "out.csv"
    status, _, err = run_cli(capsys, "mul", "eval", "--pairs", str(pairs), "--out", str(out))
    assert status == 2
    assert len(err.strip().splitlines()) == 1
    assert re.search(message, err), err
    assert not out.exists()


def test_bad_parameter_file_gives_one_line_and_status_2(tmp_path, capsys):
    bad = tmp_path / "p.json"
    bad.write_text('{"kind": "mbn.multiplier",\n "network": {"W": [[1, 2]]')
    status, _, err = run_cli(
        capsys, "mul", "report", "--params", str(bad), "--out", str(tmp_path / "x.png")
    )
    assert status == 2
    assert "p.json:2: invalid JSON" in err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["mul", "train", "--neurons", "0"], "--neurons: must be in [1, 64], got 0"),
        (["mul", "train", "--restarts", "1000000000"], "--restarts: must be in [1, 100000]"),
        (["pnn", "check", "--sequences", "1e9"], "--sequences: '1e9' is not an integer"),
        (["pnn", "check", "--sequences", "1000000000"], "--sequences: must be in [1, 100000]"),
        (["pnn", "check", "--seconds", "1e12"], "--seconds: must be at most 3600 s, got 1e12"),
    ],
)
def test_bad_flag_values_exit_with_status_2(capsys, argv, message):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and message in err, err


def test_existing_output_survives_a_failed_run(tmp_path, capsys):
    out = tmp_path / "out.csv"
    out.write_text("precious\n")
    pairs = tmp_path / "in.csv"
    pairs.write_text("x1,x2\n0.1,oops\n")
    status, _, _ = run_cli(capsys, "mul", "eval", "--pairs", str(pairs), "--out", str(out))
    assert status == 2
    assert out.read_text() == "precious\n"
    assert not any(p.name.endswith(".tmp") for p in tmp_path.iterdir())
