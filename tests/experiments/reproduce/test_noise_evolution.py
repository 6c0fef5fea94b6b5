"""The reproduction under the run's ``[noise]`` (docs/noise.md, "Evolving under noise"): its
stages evolve, validate and test under it, drawing from their own keys; off, nothing changes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.experiments.pipeline.runner import replace_section, run_stage
from mbn.experiments.reproduce import REPRODUCE
from mbn.world.sensors import NoiseConfig

from .test_stages import _copy as copy_quick_run

#: The issue's realistic level.
REALISTIC = NoiseConfig(sonar_std=0.02, sonar_dropout=0.01, wheel_std=0.05, camera_miss=0.05)


def _copy(quick_run, tmp_path, noise: NoiseConfig):
    """A copy of the quick run (as the stage tests make), its config under ``noise``."""
    rundir, seed, config = copy_quick_run(quick_run, tmp_path)
    return rundir, seed, replace_section(config, noise)


def test_the_noise_section_is_off_by_default_and_read_from_toml(tmp_path):
    assert REPRODUCE.config()["noise"] == NoiseConfig()
    (tmp_path / "n.toml").write_text("[noise]\nsonar_std = 0.02\nwheel_std = 0.05\n")
    from mbn.config import read_toml

    config = REPRODUCE.config(document=read_toml(tmp_path / "n.toml"))
    assert config["noise"].sonar_std == 0.02 and config["noise"].wheel_std == 0.05
    (tmp_path / "bad.toml").write_text("[noise]\nsonar_dropout = 2\n")
    with pytest.raises(MbnInputError, match=r"bad\.toml:2: noise\.sonar_dropout"):
        REPRODUCE.config(document=read_toml(tmp_path / "bad.toml"))


def test_a_pm_evolved_on_robot_episodes_under_noise_is_refused(quick_run, tmp_path):
    rundir, seed, config = _copy(quick_run, tmp_path, REALISTIC)
    config = replace_section(config, dataclasses.replace(config["pm"], reward="memory"))
    with pytest.raises(MbnInputError, match=r"pm\.reward = 'memory'.*\[noise\] is not supported"):
        run_stage(REPRODUCE, rundir, "pm", seed=seed, config=config)


@pytest.mark.slow
def test_the_tests_and_the_follower_evolution_run_under_the_runs_noise(quick_run, tmp_path):
    """Under realistic noise the tests' trajectories differ from the quick run's (the same
    trials without noise) and are the same when run again; RF's evolution too."""
    rundir, seed, config = _copy(quick_run, tmp_path, REALISTIC)
    clean = {n: rundir.read_stage(n) for n in ("tests", "rf")}
    noisy = run_stage(REPRODUCE, rundir, "tests", seed=seed, config=config)
    again = run_stage(REPRODUCE, rundir, "tests", seed=seed, config=config)
    assert noisy["details"] == again["details"]
    stall = lambda d: np.concatenate([np.asarray(v["stall"]) for v in d["details"].values()])  # noqa: E731
    assert not np.allclose(stall(noisy), stall(clean["tests"]), rtol=0, atol=1e-6)
    for f in ("checkpoints/rf.npz", "checkpoints/rf_restart1.npz"):
        (rundir.root / f).unlink(missing_ok=True)
    rf = run_stage(REPRODUCE, rundir, "rf", seed=seed, config=config)
    assert rf["best_fitness"] != clean["rf"]["best_fitness"]
