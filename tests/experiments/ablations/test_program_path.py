"""The ``ablations`` stage of ``mbn run ablations`` on the session's quick reproduction: every
ablation's row, the unchanged MBN equal to the reproduction's own tests, and the rebuilt
interpreters' settings. CI leaves out the two slowest ablations (τ/20 and τ/50: 40 and 100
multiplier sub-steps, the code path of τ/5 and τ/10); a slow test runs τ/50.

The tests that read the stage's run are slow (about 1.5 min on 2 cores each: left out of CI, run
with ``pytest -m slow``); the checks of its settings run in CI."""

from __future__ import annotations

import shutil

import pytest

from mbn.experiments.ablations import ABLATIONS
from mbn.experiments.pipeline import RunDir
from mbn.experiments.pipeline.runner import replace_section, run_stage
from mbn.experiments.stages.ablations import VARIANTS

#: The ablations the CI fixture runs.
CI_VARIANTS = tuple(v for v in VARIANTS if v not in ("tau_20", "tau_50"))


def _ablations(quick_run, folder, variants):
    out, _ = quick_run
    shutil.copytree(out, folder)
    rundir = RunDir(folder)
    config = ABLATIONS.config(quick=True)
    tests = config["tests"]
    section = config["ablations"].replace(
        jitter_per_mark=tests.jitter_per_mark,
        heldout_repeats=tests.heldout_repeats,
        variants=variants,
    )
    config = replace_section(config, section)
    return rundir, run_stage(ABLATIONS, rundir, "ablations", seed=3, config=config)


@pytest.fixture(scope="session")
def ablations(quick_run, tmp_path_factory):
    return _ablations(quick_run, tmp_path_factory.mktemp("ablations") / "run", CI_VARIANTS)


@pytest.mark.slow
def test_every_ablation_has_its_row(ablations):
    _, data = ablations
    rows = data["variants"]
    assert list(rows) == list(CI_VARIANTS)
    for name, row in rows.items():
        for test in ("mbn_jitter", "mbn_heldout"):
            r = row[test]
            assert r["trials"] > 0 and r["rate"] == pytest.approx(r["successes"] / r["trials"])
            assert r["wilson95"][0] <= r["rate"] <= r["wilson95"][1]
        # agreement is measured where the interpreter changes (or is the run's), not otherwise
        has = name not in ("wrong_program", "frozen_program")
        assert ("agreement" in row) == has, name
        if has:
            assert set(row["agreement"]) == {"rf_jitter", "rf_heldout", "lf_jitter", "lf_heldout"}
            assert all(0.0 <= v <= 1.0 for v in row["agreement"].values())


@pytest.mark.slow
def test_the_ablations_are_tests_a_sweep_tabulates(ablations):
    """``results.json`` records every ablation's trials as tests (``mbn sweep --experiment
    ablations`` compares them over seeds): the MBN's, and the interpreter's where it changes;
    the sweep's report tabulates each of them."""
    from mbn.experiments.ablations import ablation_tests
    from mbn.experiments.ablations.sweep import ABLATIONS_SPEC
    from mbn.experiments.sweep.summary import summarize

    _, data = ablations
    tests = ablation_tests(data["variants"])
    expected = {f"{v}_mbn_{x}" for v in CI_VARIANTS for x in ("jitter", "heldout")}
    expected |= {
        f"{v}_im_{net}_jitter"
        for v in CI_VARIANTS
        if v not in ("wrong_program", "frozen_program")
        for net in ("rf", "lf")
    }
    assert set(tests) == expected
    assert set(tests) <= set(ABLATIONS_SPEC.tests)
    assert [t for t in ABLATIONS_SPEC.tests if t.endswith("_mbn_jitter")] == [
        f"{v}_mbn_jitter" for v in VARIANTS
    ]
    row = data["variants"]["as_run"]["mbn_jitter"]
    assert tests["as_run_mbn_jitter"] == {
        "trials": row["trials"],
        "successes": row["successes"],
        "success_rate": row["rate"],
    }
    s = summarize({0: {"tests": tests}, 1: {"tests": tests}}, spec=ABLATIONS_SPEC)
    pooled = s["tests"]["as_run_mbn_jitter"]["pooled"]
    assert pooled["trials"] == 2 * row["trials"] and pooled["successes"] == 2 * row["successes"]
    assert s["tests"]["tau_50_mbn_jitter"]["rates"] == []  # not run here: no rate, no crash


@pytest.mark.slow
def test_the_unchanged_mbn_is_the_reproductions_tests(ablations):
    rundir, data = ablations
    stage = rundir.read_stage("tests")
    tests, agreement = stage["tests"], stage["agreement"]
    row = data["variants"]["as_run"]
    for x in ("jitter", "heldout"):
        assert row[f"mbn_{x}"]["successes"] == tests[f"mbn_{x}"]["successes"]
        for net in ("rf", "lf"):
            assert row["agreement"][f"{net}_{x}"] == pytest.approx(
                agreement[f"im_{net}_{x}"]["rate"]
            )
    assert data["networks"]["rf_jitter"]["successes"] == tests["rf_jitter"]["successes"]


@pytest.mark.slow
def test_the_rebuilt_interpreters_keep_the_multipliers_training_step(ablations):
    _, data = ablations
    rows = data["variants"]
    for name, ratio, substeps in (("tau_5", 0.2, 10), ("tau_10", 0.1, 20)):
        assert rows[name]["interpreter"]["tau_ratio"] == ratio
        assert rows[name]["interpreter"]["substeps"] == substeps
        assert rows[name]["interpreter"]["multiplier_neurons"] == 6
    assert rows["mul3"]["interpreter"]["multiplier_neurons"] == 3
    # exact products: the networks the programs decode to are RF and LF, up to rounding
    exact = rows["exact_products"]["agreement"]
    assert exact["rf_jitter"] >= 0.9 and exact["lf_jitter"] >= 0.9


@pytest.mark.slow
def test_multipliers_at_tau_over_50_take_100_sub_steps(quick_run, tmp_path):
    _, data = _ablations(quick_run, tmp_path / "run", ("tau_50",))
    row = data["variants"]["tau_50"]
    assert row["interpreter"]["tau_ratio"] == 0.02 and row["interpreter"]["substeps"] == 100
    assert row["mbn_jitter"]["trials"] > 0
