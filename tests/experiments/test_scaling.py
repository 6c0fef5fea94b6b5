"""MBNs of K behaviours (``mbn run scaling``): growing a program module, its code error, the
settings, and forgetting on the same mazes."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.experiments.generalization import GeneralizationResult
from mbn.experiments.program_module import PMGenome
from mbn.experiments.scaling.report import claims, forgetting
from mbn.experiments.stages.scaling import (
    STAGE_CLASSES,
    ScalingSettings,
    code_errors,
    grow_population,
    scaling_stages,
)


def test_a_grown_program_module_keeps_the_old_weights_in_place():
    rng = np.random.default_rng(0)
    k = 3
    old = rng.uniform(-5, 5, (4, PMGenome(programs=k, inputs=k).size))
    new = grow_population(old, k, jax.random.key(1), 10.0)
    assert new.shape == (4, PMGenome(programs=k + 1, inputs=k + 1).size)
    before = PMGenome(programs=k, inputs=k).network(old)
    after = PMGenome(programs=k + 1, inputs=k + 1).network(new)
    np.testing.assert_array_equal(np.asarray(after.W)[:, :k, :k], np.asarray(before.W))
    np.testing.assert_array_equal(np.asarray(after.WE)[:, :k, :k], np.asarray(before.WE))
    np.testing.assert_array_equal(np.asarray(after.bias)[:, :k], np.asarray(before.bias))
    # the new neuron's and input's genes: drawn in the bounds, not all equal
    fresh = np.concatenate(
        [np.asarray(after.W)[:, k, :].ravel(), np.asarray(after.WE)[:, :, k].ravel()]
    )
    assert np.all(np.abs(fresh) <= 10.0) and np.std(fresh) > 1.0
    # the same key, the same population
    np.testing.assert_array_equal(new, grow_population(old, k, jax.random.key(1), 10.0))
    with pytest.raises(MbnInputError, match="a 3-kind population has 21 genes"):
        grow_population(old[:, :-1], k, jax.random.key(1), 10.0)


def test_the_code_error_is_the_largest_distance_from_each_tile_kind_s_code():
    codes = [np.array([0.98, 0.01, 0.0]), np.array([0.1, 0.7, 0.05]), None]
    assert code_errors(codes) == pytest.approx([0.02, 0.3, 1.0])


def test_one_stage_per_k_each_needing_the_one_before():
    stages = scaling_stages()
    assert [s.name for s in stages] == ["mbn_k2", "mbn_k3", "mbn_k4", "mbn_k5", "mbn_k6"]
    assert stages[0].needs == ("im_full", "programs")
    assert stages[3].needs == ("im_full", "programs", "mbn_k4")
    assert len({s.key_id for s in stages}) == 5
    assert STAGE_CLASSES[4]().outputs == ("controllers/mbn_k4.json",)


@pytest.mark.parametrize(
    ("rules", "message"),
    [
        (("right", "left", "straight-right"), "6 different rules"),
        (
            ("left", "right", "straight-right", "straight-left", "right-left", "left-right"),
            "the first two are RF's and LF's",
        ),
        (("right", "left", "up", "straight-left", "right-left", "left-right"), "unknown rule"),
    ],
)
def test_settings_refuse_rules_the_mbns_cannot_grow_by(rules, message):
    with pytest.raises(MbnInputError, match=message):
        ScalingSettings(rules=rules)


def _split(rates: list[float], trials: int = 10) -> dict:
    rows = [
        {"maze": f"tiles3:{i}", "trials": trials, "successes": round(r * trials), "timed_out": 0}
        for i, r in enumerate(rates)
    ]
    k = sum(r["successes"] for r in rows)
    n = trials * len(rows)
    at = sum(r["successes"] / trials >= 0.95 for r in rows)
    return {
        "mazes": rows,
        "pooled": {
            "trials": n,
            "successes": k,
            "timed_out": 0,
            "success_rate": k / n,
            "wilson95": [0.0, 1.0],
        },
        "mazes_at_95": at,
        "fraction_of_mazes_at_95": at / len(rows),
        "seconds": 100.0,
        "failures": {"failed": n - k, "wrong_exit": 0, "stalled": n - k, "timed_out": 0},
        "meets_targets": k / n >= 0.95 and at >= 0.9 * len(rows),
    }


def _judged(name: str, split: dict) -> dict:
    return {"file": "f", "behavior": "tiles", "program": None, "family": "tiles3",
            "splits": {"test": split}}  # fmt: skip


def test_forgetting_is_the_change_on_the_same_mazes_with_a_paired_interval():
    before = [1.0] * 18 + [0.9, 0.8]  # 98.5 %
    after = [1.0] * 16 + [0.9, 0.9, 0.9, 0.8]  # 97.5 %
    data = GeneralizationResult.from_json(
        {
            "controllers": {
                "mbn_k3": _judged("mbn_k3", _split(before)),
                "mbn_k4_on_tiles3": _judged("mbn_k4_on_tiles3", _split(after)),
            },
            "noise": None,
        }
    )
    f = forgetting(data, 4)
    assert f["points"] == pytest.approx(-1.0) and f["mazes"] == 20
    assert f["low"] <= -1.0 <= f["high"] and f["low"] < f["high"]
    assert forgetting(data, 3) is None  # mbn_k2 and mbn_k3_on_tiles2 not judged


def test_the_claims_judge_forgetting_by_two_points():
    rows = claims_rows(before=[1.0] * 20, after=[1.0] * 17 + [0.9, 0.8, 0.6])  # -3.5 points
    forgot = [r for r in rows if "forgetting" in r["claim"]]
    assert len(forgot) == 1 and forgot[0]["pass"] is False
    assert forgot[0]["target"] == "|change| <= 2 points"
    assert "-3.5 points" in forgot[0]["measured"]


def claims_rows(before: list[float], after: list[float]) -> list[dict]:
    def mbn(k: int) -> dict:
        return {
            "k": k, "tile_rules": ["right", "left", "straight-right", "straight-left"][:k],
            "best_genome": [0.0], "best_fitness": 1.0, "generations": 1,
            "history": {"best": [1.0], "mean": [1.0]}, "evaluations": 36, "grown": k > 2,
            "latched_codes": {}, "code_errors": {"right": 0.01}, "initial": "right",
            "sha256": "0" * 64, "sha256_checked": True,
        }  # fmt: skip

    judged = {
        "controllers": {
            "mbn_k3": _judged("mbn_k3", _split(before)),
            "mbn_k4": _judged("mbn_k4", _split([1.0] * 20)),
            "mbn_k4_on_tiles3": _judged("mbn_k4_on_tiles3", _split(after)),
        },
        "noise": None,
    }
    return claims({"mbn_k3": mbn(3), "mbn_k4": mbn(4), "generalization": judged})


def test_over_runs_forgetting_is_met_in_nine_tenths_of_the_runs(tmp_path):
    from mbn.experiments.scaling.over_runs import scaling_over_runs, statistics

    def run(points: float, meets: bool) -> dict:
        row = {
            "test": {"success_rate": 0.97, "meets": meets, "mazes_at_95": 92, "mazes": 100},
            "forgetting": {"points": points, "low": points - 1, "high": points + 1, "mazes": 100},
            "code_error_worst": 0.05,
            "pm_evaluations": 27018,
        }
        return {"scaling": {"3": row}}

    runs = {s: run(0.5, True) for s in range(18)} | {18: run(-2.5, False), 19: run(3.0, True)}
    k3 = statistics(runs)["ks"]["3"]
    assert k3["forgetting_within"] == 18 and k3["forgetting_runs"] == 20 and k3["forgetting_meets"]
    assert k3["test_meets"] == 19 and k3["test_missed"] == [18]
    runs[17] = run(-2.1, True)  # 17 of 20 within: not met
    assert not statistics(runs)["ks"]["3"]["forgetting_meets"]
    (tmp_path / "figures").mkdir()  # the sweep makes it before its analysis
    stats, sections, figures = scaling_over_runs(tmp_path, runs)
    assert stats["runs"] == 20
    assert (tmp_path / figures[0][0]).is_file()
    assert "17/20 (not met)" in sections[0].table[1][0][3]


@pytest.mark.slow
def test_mbn_run_scaling_quick_grows_every_k_with_the_interpreter_unchanged(tmp_path):
    import json
    import subprocess
    import sys

    out = tmp_path / "run"
    done = subprocess.run(
        [sys.executable, "-m", "mbn", "run", "scaling", "--quick", "--quiet", "--seed", "3",
         "--out", str(out)],
        capture_output=True, text=True, timeout=3000,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    results = json.loads((out / "results.json").read_text())
    assert sorted(results["scaling"], key=int) == ["2", "3", "4", "5", "6"]
    digest = json.loads((out / "stages" / "im_full.json").read_text())["sha256"]
    for k, row in results["scaling"].items():
        mbn = json.loads((out / "stages" / f"mbn_k{k}.json").read_text())
        assert mbn["sha256"] == digest and mbn["sha256_checked"]
        assert len(mbn["tile_rules"]) == int(k) and row["test"]["mazes"] == 2
        assert mbn["grown"] == (int(k) > 2)
        assert (int(k) > 2) == (row["forgetting"] is not None)
    assert (out / "report.html").is_file() and (out / "figures" / "scaling.png").is_file()
