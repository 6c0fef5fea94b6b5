"""The test protocol: jittered starts, judging junction passes, and running trials."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.experiments.trials import (
    TrialGroup,
    TrialSpec,
    judge,
    run_trial_groups,
    run_trials,
    summary,
    trial_starts,
)
from mbn.world.mazes.builtin import builtin_maze, crossroad
from mbn.world.mazes.model import Maze

from .test_crossroads import stats

R, S, L, BACK = 1, 2, 3, 0


def passes(exits, right, left, tiles=None, n=None, stall=0.0, out_step=100, stalls=0):
    """Synthetic stats of one episode with the given junction passes."""
    k = len(exits)
    pad = lambda v: np.array([list(v) + [-1] * (8 - len(v))])  # noqa: E731
    return stats(
        n_junctions=np.array([k if n is None else n]),
        junction_exit=pad(exits),
        junction_right=pad(right),
        junction_left=pad(left),
        junction_tile=pad(tiles or [0] * k),
        junction_exit_step=pad([out_step] * k),
        junction_stalls=pad([stalls] * k),
        stall_fraction=np.array([stall]),
    )


def test_judging_the_right_rule():
    spec = TrialSpec(behavior="right")
    ok = judge(passes([R, S, R], right=[R, S, R], left=[L, S, L]), spec)
    assert ok["success"].tolist() == [True] and ok["correct"].tolist() == [3]
    wrong = judge(passes([R, L, R], right=[R, S, R], left=[L, L, L]), spec)
    assert wrong["success"].tolist() == [False] and wrong["correct"].tolist() == [2]
    short = judge(passes([R, S], right=[R, S], left=[L, S]), spec)
    assert short["success"].tolist() == [False] and short["judged"].tolist() == [2]
    # 3 stalled moves in the 100 steps until the third junction was left: 3 % > 2 %
    stalled = judge(passes([R, S, R], right=[R, S, R], left=[L, S, L], stalls=3), spec)
    assert stalled["success"].tolist() == [False]
    assert stalled["stall"][0] == pytest.approx(0.03)
    fine = judge(passes([R, S, R], right=[R, S, R], left=[L, S, L], stalls=2), spec)
    assert fine["success"].tolist() == [True]


def test_judging_tiles_follows_the_tile_in_force():
    spec = TrialSpec(behavior="tiles", initial="left")
    # before any tile: left rule; then a two-colour tile (left); then a one-colour tile (right)
    s = passes([L, L, R], right=[R, R, R], left=[L, L, L], tiles=[0, 2, 1])
    assert judge(s, spec)["success"].tolist() == [True]
    s = passes([R, L, R], right=[R, R, R], left=[L, L, L], tiles=[0, 2, 1])
    assert judge(s, spec)["success"].tolist() == [False]
    assert judge(s, TrialSpec(behavior="tiles", initial="right"))["success"].tolist() == [True]


def test_summary_counts():
    v = {
        "success": np.array([True, False]),
        "correct": np.array([3, 1]),
        "judged": np.array([3, 2]),
        "stall": np.array([0.0, 0.1]),
    }
    assert summary(v) == {
        "trials": 2,
        "successes": 1,
        "success_rate": 0.5,
        "junctions": 5,
        "correct_junctions": 4,
        "mean_stall_fraction": pytest.approx(0.05),
    }


def test_trial_starts_are_the_marks_then_jittered_copies():
    maze = builtin_maze("fig4")
    spec = TrialSpec(repeats=4, seed=2)
    p = trial_starts(maze, spec)
    assert p.shape == (4 * len(maze.starts), 3)
    np.testing.assert_array_equal(p[::4], maze.starts)
    for m, (x, y, th) in enumerate(maze.starts):
        d = p[4 * m + 1 : 4 * m + 4] - [x, y, th]
        along = d[:, 0] * math.cos(th) + d[:, 1] * math.sin(th)
        lateral = -d[:, 0] * math.sin(th) + d[:, 1] * math.cos(th)
        assert np.all(np.abs(along) <= 0.3 + 1e-12) and np.all(np.abs(lateral) <= 0.15 + 1e-12)
        assert np.all(np.abs(d[:, 2]) <= math.radians(10) + 1e-12)
    np.testing.assert_array_equal(trial_starts(maze, spec), p)


def test_bad_specs_and_mazes():
    with pytest.raises(MbnInputError, match="behavior"):
        TrialSpec(behavior="up")
    with pytest.raises(MbnInputError, match="repeats"):
        TrialSpec(repeats=0)
    with pytest.raises(MbnInputError, match="has none"):
        TrialSpec(behavior="tiles").check_maze(crossroad("LSR"))
    no_starts = Maze(
        "bare",
        walls=crossroad("S").walls,
        bounds=(0, 8.4, 0, 8.4),
        grid=crossroad("S").grid,
        cell=1.2,
    )
    with pytest.raises(MbnInputError, match="no start marks"):
        TrialSpec().check_maze(no_starts)


def test_a_scripted_right_turn_passes_a_one_junction_trial():
    """Run real trials: a robot that drives north and turns right at the plus crossing."""
    maze = crossroad("LSR")

    def turn_right(state, obs):
        step = state
        v = jnp.where((step >= 72) & (step < 82), 0.0, 0.5)
        w = jnp.where((step >= 72) & (step < 82), -math.pi / 2, 0.0)
        return step + 1, (v, w)

    spec = TrialSpec(behavior="right", junctions=1, seconds=12.0)
    verdict, _, _ = run_trials(maze, spec, turn_right, lambda n: jnp.zeros(n, jnp.int32))
    assert verdict["success"].tolist() == [True]
    left = TrialSpec(behavior="left", junctions=1, seconds=12.0)
    assert run_trials(maze, left, turn_right, lambda n: jnp.zeros(n, jnp.int32))[0][
        "success"
    ].tolist() == [False]


def test_judging_tiles_can_skip_the_junctions_before_the_first_tile():
    spec = TrialSpec(behavior="tiles", initial="none")
    # a wrong turn before any tile is not judged; the three after the tiles are
    s = passes([L, R, L, L], right=[R, R, R, R], left=[L, L, L, L], tiles=[0, 1, 2, 2])
    v = judge(s, spec)
    assert v["success"].tolist() == [True] and v["judged"].tolist() == [3]
    s = passes([L, R, L], right=[R, R, R], left=[L, L, L], tiles=[0, 1, 2])
    assert judge(s, spec)["judged"].tolist() == [2]


def test_all_jittered_starts_when_the_marks_are_left_out():
    maze = builtin_maze("fig4")
    with_marks = trial_starts(maze, TrialSpec(repeats=3, seed=4))
    jittered = trial_starts(maze, TrialSpec(repeats=3, seed=4, exact_first=False))
    assert jittered.shape == with_marks.shape == (30, 3)
    marks = np.asarray(maze.starts)
    # no jittered start is a mark, and each lies within the jitter of its own mark
    d = np.abs(jittered.reshape(10, 3, 3) - marks[:, None, :])
    assert np.all(d.max(-1) > 0)
    assert np.all(np.hypot(d[..., 0], d[..., 1]) <= math.hypot(0.15, 0.3) + 1e-9)
    assert np.all(d[..., 2] <= math.radians(10) + 1e-9)


def test_trial_groups_judge_each_group_as_run_trials_would():
    """Two tests of one controller function in one rollout, in two mazes, with two rules: each
    verdict equals that of its own run_trials."""

    def turn_right(state, obs):
        step = state
        v = jnp.where((step >= 72) & (step < 82), 0.0, 0.5)
        w = jnp.where((step >= 72) & (step < 82), -math.pi / 2, 0.0)
        return step + 1, (v, w)

    init = lambda n: jnp.zeros(n, jnp.int32)  # noqa: E731
    mazes = [crossroad("LSR"), crossroad("SR")]
    right = TrialSpec(behavior="right", junctions=1, seconds=12.0, repeats=3, seed=2)
    left = TrialSpec(behavior="left", junctions=1, seconds=12.0, repeats=2, seed=5)
    groups = [TrialGroup("a", 0, right, init), TrialGroup("b", 1, left, init)]
    verdicts, _, slices, poses = run_trial_groups(mazes, groups, turn_right, seconds=12.0)
    assert slices == {"a": slice(0, 3), "b": slice(3, 5)}
    assert poses.shape == (5, 3)
    for name, maze, spec in (("a", mazes[0], right), ("b", mazes[1], left)):
        alone, _, _ = run_trials(maze, spec, turn_right, init)
        for k in ("success", "correct", "judged", "stall", "exits"):
            np.testing.assert_array_equal(verdicts[name][k], alone[k], err_msg=f"{name} {k}")
    assert verdicts["a"]["success"].all()
    with pytest.raises(MbnInputError, match="distinct names"):
        run_trial_groups(mazes, groups[:1] * 2, turn_right, seconds=1.0)
