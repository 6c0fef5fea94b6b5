"""The experiments a sweep runs: the reproduction (the default) and new-behaviours, each with its
own per-run targets, read from where its ``results.json`` keeps them."""

from __future__ import annotations

import pytest

from mbn.errors import MbnInputError
from mbn.experiments.behaviours.sweep import NEW_BEHAVIOURS_SPEC, NEW_BEHAVIOURS_TARGETS
from mbn.experiments.registry import registered
from mbn.experiments.reproduce.sweep import REPRODUCE_SPEC
from mbn.experiments.sweep.run import SweepSettings, check_sweep_dir, write_sweep
from mbn.experiments.sweep.specs import sweep_spec
from mbn.experiments.sweep.summary import seed_verdict, summarize
from mbn.experiments.sweep.targets import TARGETS, measure


def test_every_registered_experiment_has_its_sweep_view_named_after_it():
    for name, registration in registered().items():
        spec = sweep_spec(name)
        assert spec.name == name and spec.load() is registration.load()
        assert spec.command == ("mbn reproduce" if name == "reproduce" else f"mbn run {name}")
    assert sweep_spec(None) is REPRODUCE_SPEC and REPRODUCE_SPEC.targets == TARGETS
    assert sweep_spec("ablations").load().name == "ablations"
    assert sweep_spec("noise").load().name == "noise"
    with pytest.raises(MbnInputError, match="experiment 'nope': not a registered experiment"):
        sweep_spec("nope")


def _nb_results(**overrides):
    """A new-behaviours ``results.json`` as the experiment writes it: every test of the spec,
    the interpreter's agreements in ``stages.im_full``, the decoded networks' in
    ``stages.tests3``; every figure at its best unless overridden."""
    tests = {}
    for name in NEW_BEHAVIOURS_SPEC.tests:
        n = 220 if name.endswith("_jitter") else 187 if name.endswith("_heldout") else 11
        k = overrides.get(name, n)
        tests[name] = {"trials": n, "successes": k, "success_rate": k / n}
    agreement: dict[str, dict[str, dict]] = {"im_full": {}, "tests3": {}}
    for t in NEW_BEHAVIOURS_TARGETS:
        if t.source == "agreement":
            stage = t.where[1]
            agreement[stage][t.test] = {
                "trials": 220,
                "same_branches": overrides.get(t.name, 220),
                "rate": overrides.get(t.name, 220) / 220,
            }
    return {
        "tests": tests,
        "stages": {s: {"agreement": a} for s, a in agreement.items()},
        "claims": [{"claim": "a new behaviour", "pass": True, "target": "marks all"}],
    }


def test_new_behaviours_targets_are_read_where_the_experiment_records_them():
    r = _nb_results(agreement_im_full_lf_jitter=215, mbn3_two_tiles_heldout=170)
    lf = next(t for t in NEW_BEHAVIOURS_TARGETS if t.name == "agreement_im_full_lf_jitter")
    assert lf.path == ("stages", "im_full", "agreement", "im_full_lf_jitter")
    assert measure(lf, r) == (215, 220)
    v = seed_verdict(r, NEW_BEHAVIOURS_TARGETS)
    # 215/220 = 97.7 % < 98 %; 170/187 = 90.9 % < 95 %
    assert v["missed"] == ["agreement_im_full_lf_jitter", "mbn3_two_tiles_heldout"]
    assert seed_verdict(_nb_results(), NEW_BEHAVIOURS_TARGETS)["meets_all"]
    # a run without the record misses the target (no trials), it does not crash the summary
    del r["stages"]["tests3"]
    assert (
        "agreement_im_full_straight_right_jitter"
        in seed_verdict(r, NEW_BEHAVIOURS_TARGETS)["missed"]
    )


def test_a_new_behaviours_summary_counts_its_own_targets_and_claims():
    runs = {0: _nb_results(), 1: _nb_results(im_full_straight_right=10), 2: None}
    s = summarize(runs, {2: "RuntimeError: boom"}, NEW_BEHAVIOURS_SPEC)
    assert s["meet_every_target"] == 1 and s["per_seed"]["1"]["missed"] == [
        "im_full_straight_right"
    ]
    assert set(s["targets"]) == {
        t.name for t in (*NEW_BEHAVIOURS_TARGETS, *NEW_BEHAVIOURS_SPEC.generalization)
    }
    # runs without a generalization stage meet no generalization target, counted apart
    assert s["meet_every_generalization_target"] == 0
    assert s["per_seed"]["0"]["meets_all"] and not s["per_seed"]["0"]["meets_generalization"]
    assert s["tests"]["mbn3_jitter"]["pooled"] == {
        "successes": 440,
        "trials": 440,
        "wilson95": pytest.approx(s["tests"]["mbn3_jitter"]["pooled"]["wilson95"]),
    }
    # its claims name a target, not a criterion: the summary shows the target
    assert s["claims"] == [
        {"claim": "a new behaviour", "runs": 2, "hold": 2, "judged": 2, "criterion": "marks all"}
    ]


def test_the_experiment_is_a_setting_of_the_sweep(tmp_path):
    from mbn.experiments.behaviours import NEW_BEHAVIOURS
    from mbn.experiments.reproduce import REPRODUCE

    nb = SweepSettings((0, 1), NEW_BEHAVIOURS.config(quick=True), "new-behaviours")
    assert nb.to_dict()["experiment"] == "new-behaviours"
    repro = SweepSettings((0, 1), REPRODUCE.config(quick=True))
    assert "experiment" not in repro.to_dict()  # a reproduction's sweep.json as before
    out = tmp_path / "s"
    out.mkdir()
    write_sweep(out, {"kind": "mbn.sweep", "settings": nb.to_dict(), "runs": {}})
    with pytest.raises(MbnInputError, match="holds a sweep with other settings"):
        check_sweep_dir(out, repro)
    assert check_sweep_dir(out, nb) is not None
