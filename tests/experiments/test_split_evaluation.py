"""``mbn evaluate`` over a split of a maze family (``docs/generalization.md``), with the session's
quick reproduction's RF: one line per maze, the pooled figures, and each maze judged as it is
alone."""

from __future__ import annotations

import json

import pytest

from mbn.cli.main import main

KEYS = {"trials", "successes", "success_rate", "timed_out", "junctions", "correct_junctions"}


def run(capsys, *args):
    status = main(["evaluate", *map(str, args)])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


# slow: a second path; CI checks that a batch gives each genome its value alone (test_batching.py)
@pytest.mark.slow
def test_a_split_is_judged_maze_by_maze_as_each_maze_alone(quick_run, capsys):
    """``--maze FAMILY/SPLIT:A-B``: one line per maze and the pooled figures; each maze's row is
    what evaluating that maze alone gives (the same trials, batched with the others)."""
    out, _ = quick_run
    lf = out / "controllers" / "lf.json"  # the quick run's LF: some trials pass, some fail
    common = ["--controller", lf, "--behavior", "left", "--seconds", 60, "--json"]
    status, out, _ = run(capsys, *common, "--maze", "grid/validation:0-2")
    assert status == 0
    data = json.loads(out)
    assert data["split"] == "grid/validation:0-2" and data["seconds"] == 60
    assert [r["maze"] for r in data["mazes"]] == [f"grid:{s}" for s in range(1_000_000, 1_000_003)]
    for row in data["mazes"]:
        status, alone, _ = run(capsys, *common, "--maze", row["maze"])
        assert status == 0
        assert {k: row[k] for k in KEYS} == {
            k: v for k, v in json.loads(alone).items() if k in KEYS
        }
    pooled = data["pooled"]
    assert pooled["trials"] == 30 and pooled["successes"] == sum(
        r["successes"] for r in data["mazes"]
    )
    assert data["mazes_at_95"] == sum(r["success_rate"] >= 0.95 for r in data["mazes"])
    assert 0 < pooled["successes"] < pooled["trials"]  # rows that can differ
    status, text, _ = run(capsys, *common[:-1], "--maze", "grid/validation:0-1")
    assert status == 0 and "grid:1000001" in text and "pooled:" in text


def test_pooled_rows_sum_the_mazes_and_count_those_at_the_target():
    from mbn.experiments.generalization import pooled_rows

    rows = [
        {"trials": 10, "successes": 10, "timed_out": 0, "success_rate": 1.0},
        {"trials": 10, "successes": 9, "timed_out": 1, "success_rate": 0.9},
        {"trials": 20, "successes": 19, "timed_out": 0, "success_rate": 0.95},
    ]
    out = pooled_rows(rows)
    assert out["pooled"] == {"trials": 40, "successes": 38, "timed_out": 1, "success_rate": 0.95}
    assert out["mazes_at_95"] == 2
    assert abs(out["fraction_of_mazes_at_95"] - 2 / 3) < 1e-12
