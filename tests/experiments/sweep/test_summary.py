"""The statistics of a sweep: Wilson intervals, quartiles, the targets."""

from __future__ import annotations

import math

import pytest
from scipy.stats import binomtest

from mbn.experiments.sweep.summary import describe, seed_verdict, summarize, wilson_interval
from mbn.experiments.sweep.targets import TARGETS, meets
from tests.split_records import split_record_of


def test_wilson_interval_known_values():
    # 0 of 10: the upper bound is z^2 / (n + z^2) = 0.2775 (a textbook value)
    lo, hi = wilson_interval(0, 10)
    assert lo == 0.0
    assert hi == pytest.approx(0.27753, abs=5e-5)
    # 81 of 263 (Wilson's own kind of example): 0.2553 .. 0.3662
    lo, hi = wilson_interval(81, 263)
    assert (lo, hi) == pytest.approx((0.25527, 0.36624), abs=5e-5)
    assert wilson_interval(10, 10)[1] == pytest.approx(1.0, abs=1e-12)


def test_wilson_interval_holds_the_observed_rate_exactly():
    # in floats the formula's lower end at 0 successes was 1e-17 for n = 3, 6, 7, 12, ...
    for n in range(1, 301):
        assert wilson_interval(0, n)[0] == 0.0 and wilson_interval(n, n)[1] == 1.0
        for k in (1, n // 2, n - 1):
            lo, hi = wilson_interval(k, n)
            assert lo <= k / n <= hi


@pytest.mark.parametrize(("k", "n"), [(0, 1), (3, 7), (190, 200), (1999, 2040), (50, 50)])
def test_wilson_interval_matches_scipy(k, n):
    ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    assert wilson_interval(k, n) == pytest.approx((ci.low, ci.high), abs=1e-9)


def test_wilson_interval_without_trials_is_nan():
    assert all(math.isnan(x) for x in wilson_interval(0, 0))


def test_describe_median_and_quartiles():
    d = describe([1.0, 2.0, 3.0, 4.0])
    assert d == pytest.approx({"median": 2.5, "q1": 1.75, "q3": 3.25, "min": 1.0, "max": 4.0})
    d = describe([0.9, 0.5, 1.0])
    assert d["median"] == pytest.approx(0.9) and d["min"] == pytest.approx(0.5)
    assert math.isnan(describe([])["median"])


def test_targets_are_compared_exactly():
    jitter = next(t for t in TARGETS if t.name == "rf_jitter")
    paper = next(t for t in TARGETS if t.name == "rf")
    agree = next(t for t in TARGETS if t.name == "agreement_im_lf_jitter")
    assert meets(jitter, 190, 200) and not meets(jitter, 189, 200)
    assert meets(paper, 10, 10) and not meets(paper, 9, 10)
    assert meets(agree, 196, 200) and not meets(agree, 195, 200)
    assert not meets(jitter, 0, 0)
    assert len(TARGETS) == 17


def _results(**overrides):
    from mbn.experiments.stages.protocol import TEST_NAMES

    tests = {}
    for name in TEST_NAMES:
        n = 200 if name.endswith("_jitter") else 10
        k = overrides.get(name, n)
        tests[name] = {"trials": n, "successes": k, "success_rate": k / n}
    agreement = {
        f"im_{r}_jitter": {
            "trials": 200,
            "same_branches": overrides.get(f"agree_{r}", 200),
            "rate": overrides.get(f"agree_{r}", 200) / 200,
        }
        for r in ("rf", "lf")
    }
    return {
        "tests": tests,
        "stages": {"tests": {"agreement": agreement}},
        "claims": [{"claim": "c1", "pass": overrides.get("c1", True), "criterion": "x"}],
    }


def test_seed_verdict_names_each_missed_target():
    v = seed_verdict(_results(lf_jitter=189, mbn=9, agree_rf=195))
    assert v["meets_all"] is False
    assert v["missed"] == ["mbn", "lf_jitter", "agreement_im_rf_jitter"]
    assert seed_verdict(_results())["meets_all"] is True


def test_summarize_pools_trials_and_counts_seeds_and_claims():
    runs = {
        0: _results(),
        1: _results(rf_jitter=180, c1=False),
        2: _results(rf_jitter=199),
        3: None,
    }
    s = summarize(runs, {3: "RuntimeError: boom"})
    assert s["finished"] == 3 and s["failed"] == [3] and s["meet_every_target"] == 2
    t = s["tests"]["rf_jitter"]
    assert t["pooled"]["successes"] == 200 + 180 + 199 and t["pooled"]["trials"] == 600
    assert t["median"] == pytest.approx(0.995) and t["min"] == pytest.approx(0.9)
    assert s["targets"]["rf_jitter"]["seeds_meeting"] == 2
    assert s["per_seed"]["1"]["missed"] == ["rf_jitter"]
    assert s["per_seed"]["3"] == {"state": "failed", "error": "RuntimeError: boom"}
    assert s["claims"] == [{"claim": "c1", "runs": 3, "hold": 2, "judged": 3, "criterion": "x"}]


def test_claims_naming_a_run_s_own_connections_count_together():
    """The LF claim names the connections each run re-evolved ("; here W_21, W_22, WE_22"):
    runs that chose other connections still count towards one claim."""
    from mbn.experiments.sweep.summary import claim_key

    text = "Re-evolving 3 connections of RF gives a left-wall follower (LF) (section 3.1; here {})"
    runs = {}
    for seed, conns in enumerate(["W_21, W_22, WE_22", "W_21, WE_21, WE_22", "W_22, W_23, WE_21"]):
        r = _results()
        r["claims"] = [{"claim": text.format(conns), "pass": seed != 1, "criterion": "x"}]
        runs[seed] = r
    s = summarize(runs, {})
    key = "Re-evolving 3 connections of RF gives a left-wall follower (LF) (section 3.1)"
    assert s["claims"] == [{"claim": key, "runs": 3, "hold": 2, "judged": 3, "criterion": "x"}]
    assert claim_key("The MBN follows the right wall (section 3.2)") == (
        "The MBN follows the right wall (section 3.2)"
    )


def _split(successes: list[int], trials: int = 10) -> dict:
    """A split's record as ``results.json`` keeps it."""
    return split_record_of(successes, trials).to_json()


def test_generalization_targets_are_judged_per_seed_apart_from_the_run_targets():
    from mbn.experiments.sweep.specs import sweep_spec
    from mbn.experiments.sweep.targets import GENERALIZATION_TARGETS

    spec = sweep_spec("reproduce")
    assert spec.generalization == GENERALIZATION_TARGETS
    good = {"test": _split([10] * 9 + [5]), "zero-shot": _split([10, 8, 9])}  # 95 %, 90 %
    controllers = {n: {"splits": dict(good)} for n in ("rf", "lf", "im_rf", "im_lf", "mbn")}
    # LF: pooled 98 % but 8 of 10 mazes at 95 %; the MBN: zero-shot 26/30 < 90 %
    controllers["lf"] = {"splits": {**good, "test": _split([10] * 8 + [9, 9])}}
    controllers["mbn"] = {"splits": {**good, "zero-shot": _split([10, 8, 8])}}
    results = {"stages": {"generalization": {"controllers": controllers}}, "tests": {}}
    v = seed_verdict(results, spec.generalization)
    assert v["missed"] == ["lf_test_mazes", "mbn_zero_shot"]
    assert v["targets"]["lf_test"] == {"hits": 98, "trials": 100, "meets": True}
    assert v["targets"]["lf_test_mazes"] == {"hits": 8, "trials": 10, "meets": False}
    s = summarize({0: results}, spec=spec)
    assert s["meet_every_generalization_target"] == 0
    assert s["per_seed"]["0"]["missed_generalization"] == ["lf_test_mazes", "mbn_zero_shot"]
    assert s["targets"]["rf_test"]["group"] == "generalization"
    assert s["targets"]["rf_jitter"]["group"] == "run"
