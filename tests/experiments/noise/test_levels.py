"""The ``noise_levels`` stage of ``mbn run noise`` on the session's quick reproduction: each
channel's levels, the controllers that read it, the noiseless point equal to the reproduction's
own tests, and a channel at its extreme breaking the controllers.

The tests that read the stage's run are slow (about 1.5 min on 2 cores each: left out of CI, run
with ``pytest -m slow``); the checks of its settings run in CI."""

from __future__ import annotations

import shutil

import pytest

from mbn.errors import MbnInputError
from mbn.experiments.noise import NOISE
from mbn.experiments.noise.report import claims
from mbn.experiments.pipeline import RunDir
from mbn.experiments.pipeline.runner import replace_section, run_stage
from mbn.experiments.stages.noise_levels import CONTROLLERS, NoiseLevelsSettings


@pytest.fixture(scope="session")
def levels(quick_run, tmp_path_factory):
    out, _ = quick_run
    folder = tmp_path_factory.mktemp("noise") / "run"
    shutil.copytree(out, folder)
    rundir = RunDir(folder)
    config = NOISE.config(quick=True)
    tests = config["tests"]
    # the reproduction's test trials, so that the noiseless point is its tests
    section = config["noise_levels"].replace(
        channels=("sonar_dropout", "camera_miss", "program_std"),
        sonar_dropout=(0.0, 1.0),
        camera_miss=(0.0, 1.0),
        program_std=(0.0, 0.02),
        jitter_per_mark=tests.jitter_per_mark,
        heldout_repeats=tests.heldout_repeats,
    )
    data = run_stage(NOISE, rundir, "noise_levels", seed=3, config=replace_section(config, section))
    return rundir, data


@pytest.mark.slow
def test_every_controller_gets_the_channels_it_reads(levels):
    _, data = levels
    curves = data["curves"]
    assert set(curves) == set(CONTROLLERS)
    assert set(curves["rf"]) == {"sonar_dropout"}  # no camera, no program lines
    assert set(curves["im_rf"]) == set(curves["im_lf"]) == {"sonar_dropout", "program_std"}
    assert set(curves["mbn"]) == {"sonar_dropout", "camera_miss", "program_std"}
    for name, by_channel in curves.items():
        for channel, points in by_channel.items():
            assert [p["level"] for p in points] == list(data["levels"][channel]), (name, channel)
            for p in points:
                for test in ("jitter", "heldout"):
                    r = p[test]
                    assert r["rate"] == pytest.approx(r["successes"] / r["trials"])
                    assert r["wilson95"][0] <= r["rate"] <= r["wilson95"][1]
    assert set(data["realistic"]) == {"noise", *CONTROLLERS}
    # the quick reproduction was evolved without noise, and the claims say so
    assert data["evolved_under"] == {}
    assert "evolved without noise" in claims({"noise_levels": data})[0]["measured"]
    assert (
        "wheel_std = 0.05"
        in claims({"noise_levels": {**data, "evolved_under": {"wheel_std": 0.05}}})[0]["measured"]
    )


@pytest.mark.slow
def test_without_noise_the_trials_are_the_reproductions_tests(levels):
    rundir, data = levels
    tests = rundir.read_stage("tests")["tests"]
    for name in CONTROLLERS:
        base = next(iter(data["curves"][name].values()))[0]
        assert base["level"] == 0.0
        for test in ("jitter", "heldout"):
            assert base[test]["successes"] == tests[f"{name}_{test}"]["successes"], (name, test)
            assert base[test]["trials"] == tests[f"{name}_{test}"]["trials"]


@pytest.mark.slow
def test_sonar_dropout_at_its_extreme_breaks_every_controller(levels):
    _, data = levels
    for name in CONTROLLERS:  # every sonar reads 5 m: no wall is followed
        worst = data["curves"][name]["sonar_dropout"][-1]
        assert worst["level"] == 1.0
        assert worst["jitter"]["successes"] == 0 and worst["heldout"]["successes"] == 0


def test_levels_must_start_at_zero_and_increase():
    with pytest.raises(MbnInputError, match=r"noise_levels\.sonar_std: levels must start at 0"):
        NoiseLevelsSettings(sonar_std=(0.02, 0.05))
    with pytest.raises(MbnInputError, match="increase"):
        NoiseLevelsSettings(wheel_std=(0.0, 0.2, 0.1))
    with pytest.raises(MbnInputError, match=r"noise\.sonar_dropout"):
        NoiseLevelsSettings(sonar_dropout=(0.0, 2.0))


@pytest.mark.slow
def test_the_levels_over_runs(levels, tmp_path):
    """``mbn sweep --experiment noise``: each run's trials become tests (``noise_tests``), the
    sweep's spec names the ones it tabulates, and over runs each channel's points carry the
    runs' median, quartiles and pooled trials; a controller that does not read a channel has no
    curve; the report has a section and a figure per channel."""
    from mbn.experiments.noise.over_runs import CONTROLLER_NAMES, noise_over_runs, noise_tests
    from mbn.experiments.noise.sweep import NOISE_SPEC
    from mbn.experiments.sweep.summary import summarize

    _, data = levels
    assert tuple(CONTROLLERS) == CONTROLLER_NAMES
    tests = noise_tests(data)
    assert set(NOISE_SPEC.tests) <= set(tests)
    assert "rf_camera_miss_1_jitter" not in tests and "mbn_camera_miss_1_jitter" in tests
    drop = data["curves"]["mbn"]["sonar_dropout"][1]["jitter"]
    assert tests["mbn_sonar_dropout_1_jitter"] == {
        "trials": drop["trials"],
        "successes": drop["successes"],
        "success_rate": drop["rate"],
    }
    # a second run whose MBN passed nothing without noise
    worse = {k: dict(v) for k, v in tests.items()}
    worse["mbn_none_jitter"] = {**worse["mbn_none_jitter"], "successes": 0, "success_rate": 0.0}
    results = {
        s: {"tests": t, "levels": data["levels"], "channels": data["channels"]}
        for s, t in ((0, tests), (1, worse))
    }
    stats, sections, images = noise_over_runs(tmp_path, results)
    assert stats["runs"] == 2
    assert set(stats["channels"]) == {"sonar_dropout", "camera_miss", "program_std"}
    assert set(stats["channels"]["camera_miss"]) == {"mbn"}
    none = stats["channels"]["sonar_dropout"]["mbn"][0]
    assert none["level"] == 0.0
    rate = tests["mbn_none_jitter"]["success_rate"]
    assert none["jitter"]["rates"] == [rate, 0.0]
    assert none["jitter"]["median"] == pytest.approx(rate / 2)
    n = tests["mbn_none_jitter"]["trials"]
    assert none["jitter"]["pooled"]["trials"] == 2 * n
    assert none["jitter"]["pooled"]["successes"] == tests["mbn_none_jitter"]["successes"]
    assert [s.title for s in sections] == [f"Noise over runs: {c}" for c in stats["channels"]]
    for file, _ in images:
        assert (tmp_path / file).is_file()
    s = summarize(results, spec=NOISE_SPEC)
    assert s["tests"]["mbn_realistic_jitter"]["pooled"]["trials"] == 2 * n
