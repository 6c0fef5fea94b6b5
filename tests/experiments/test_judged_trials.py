"""Trials that stop once judged (:mod:`mbn.world.judged`): the verdicts of the whole rollout,
fewer robot-steps, on the session's quick reproduction's controllers in generated mazes."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from mbn import precision
from mbn.controllers import make_controller, read_controller_spec
from mbn.errors import MbnInputError
from mbn.experiments.trials import TrialGroup, TrialSpec, route_seconds, run_trial_groups
from mbn.world import judged as judged_module
from mbn.world.judged import batch_sizes, judged_passes
from mbn.world.mazes import families
from mbn.world.rollout import robot_steps
from mbn.world.sensors import NoiseConfig
from mbn.world.stats import start_junctions


def test_batch_sizes_shrink_by_a_factor_down_to_the_floor():
    assert batch_sizes(3000, 4, 32) == [3000, 750, 188, 47]
    assert batch_sizes(3000, 16, 32) == [3000, 188]
    assert batch_sizes(60, 4, 32) == [60]
    assert batch_sizes(10, 2, 1) == [10, 5, 3, 2, 1]
    with pytest.raises(MbnInputError, match="shrink >= 2"):
        batch_sizes(10, 1, 1)


def test_passes_count_for_the_verdict_from_the_first_tile_where_it_is_judged_so():
    log = start_junctions(3, 4)
    log = log._replace(
        passes=np.array([2, 3, 6]),
        tile=np.array([[0, 1, -1, -1], [0, 0, 2, -1], [0, 0, 0, 0]]),
    )
    assert judged_passes(log, np.array([False, False, False])).tolist() == [2, 3, 4]
    # from the first tile: the passes made before it do not count; a full log counts as full
    assert judged_passes(log, np.array([True, True, True])).tolist() == [1, 1, 4]


def _trials(quick_run, name, family, noise=None):
    out, _ = quick_run
    with precision.scope(precision.ROBOT):  # as the runs read it: its parameters in float32
        spec = read_controller_spec(out / "controllers" / f"{name}.json")
        loaded = make_controller(spec, None, check_stability=False, noise=noise)
    mazes = [families.generate(family, s) for s in families.split_seeds("validation", 0, 5, family)]
    if name == "mbn":
        trial = TrialSpec(
            behavior="tiles",
            initial=loaded.initial_rule or "right",
            tile_rules=tuple(loaded.tile_rules or ("right", "left")),
        )
    else:
        trial = TrialSpec(behavior="right")
    groups = [TrialGroup(m.name, i, trial, loaded.initial_state) for i, m in enumerate(mazes)]
    seconds = max(route_seconds(m, trial) for m in mazes)

    def run(until_judged, key=None):
        before = robot_steps()
        with precision.scope(precision.ROBOT):
            verdicts, result, _, _ = run_trial_groups(
                mazes,
                groups,
                loaded.controller,
                seconds=seconds,
                dt=loaded.dt,
                sensors=loaded.sensors,
                camera=loaded.camera,
                noise=loaded.noise,
                key=key,
                until_judged=until_judged,
            )
        return verdicts, result, robot_steps() - before

    return run


def _same_verdicts(a, b):
    assert list(a) == list(b)
    for group in a:
        for field in a[group]:
            np.testing.assert_array_equal(a[group][field], b[group][field], err_msg=field)


@pytest.mark.parametrize(
    ("name", "family"),
    [pytest.param("rf", "grid", marks=pytest.mark.slow), ("mbn", "tiles2")],
)
def test_trials_stopped_once_judged_get_the_verdicts_of_the_whole_rollout(
    quick_run, monkeypatch, name, family
):
    run = _trials(quick_run, name, family)
    whole, whole_result, whole_steps = run(False)
    # small chunks and batches, so that the batch is made smaller (and padded) several times
    monkeypatch.setattr(judged_module, "CHUNK_STEPS", 40)
    monkeypatch.setattr(judged_module, "SHRINK", 2)
    monkeypatch.setattr(judged_module, "FLOOR", 1)
    judged, result, steps = run(True)
    _same_verdicts(whole, judged)
    assert steps < whole_steps
    # a robot never judged ran the whole time: its statistics are the whole rollout's
    n = np.asarray(whole_result.stats.n_junctions)
    open_ = n < 3
    for field in ("stall_fraction", "final_pose", "distance", "n_junctions"):
        np.testing.assert_array_equal(
            np.asarray(getattr(result.stats, field))[open_],
            np.asarray(getattr(whole_result.stats, field))[open_],
            err_msg=field,
        )
    # one judged at all: its passes as far as they count are the whole rollout's
    done = ~open_
    assert done.any()
    np.testing.assert_array_equal(
        np.asarray(result.stats.junction_exit_step)[done, :3],
        np.asarray(whole_result.stats.junction_exit_step)[done, :3],
    )


def test_under_noise_the_batch_is_kept_whole_and_the_verdicts_are_the_same(quick_run):
    noise = NoiseConfig(sonar_std=0.02, wheel_std=0.05)
    run = _trials(quick_run, "rf", "grid", noise=noise)
    key = jax.random.key(3)
    whole, _, whole_steps = run(False, key)
    judged, _, steps = run(True, key)
    _same_verdicts(whole, judged)
    assert steps <= whole_steps


def test_a_recorded_trajectory_is_refused():
    from mbn.world.engine import compile_mazes
    from mbn.world.rollout import RolloutConfig

    maze = families.generate("grid", families.split_seeds("validation", 0, 0, "grid")[0])
    with pytest.raises(MbnInputError, match="record_every 0"):
        judged_module.run_rollout_until_judged(
            compile_mazes([maze]),
            lambda s, o: (s, (0.0, 0.0)),
            np.zeros((1, 1)),
            maze.starts[:1],
            np.zeros(1, np.int32),
            RolloutConfig(steps=10, record_every=1),
            judged=3,
        )
