"""The test protocol: jittered starts, judging junction passes, and running trials."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.experiments.trials import (
    MIN_SECONDS,
    TrialGroup,
    TrialSpec,
    judge,
    longest_route,
    route_seconds,
    run_trial_groups,
    run_trials,
    summary,
    trial_starts,
)
from mbn.world.junctions import rule_route
from mbn.world.mazes.builtin import builtin_maze, crossroad
from mbn.world.mazes.grid_text import parse_maze_text
from mbn.world.mazes.model import Maze

from .test_crossroads import stats

R, S, L, BACK = 1, 2, 3, 0

#: Corridors of 7.2 m between junctions: 2 x 2 blocks of 5 x 5 wall cells.
LONG_MAZE = """\
name = long
###############
#...>.......<.#
#.#####.#####.#
#.#####.#####.#
#v#####^#####.#
#.#####.#####.#
#.#####.#####.#
#.............#
#.#####.#####.#
#.#####.#####^#
#.#####v#####.#
#.#####.#####.#
#.#####.#####.#
#.>...........#
###############
"""


#: Open-exit mask bit of each exit code (back, right, straight, left): mbn.world.rules.OPEN_BITS.
BIT = {BACK: 1, R: 2, S: 4, L: 8}


def passes(exits, right, left, tiles=None, n=None, stall=0.0, out_step=100, stalls=0, opened=None):
    """Synthetic stats of one episode with the given junction passes. ``opened``: the exits open
    at each pass (codes); by default those the right and the left rule take there."""
    k = len(exits)
    pad = lambda v: np.array([list(v) + [-1] * (8 - len(v))])  # noqa: E731
    if opened is None:
        opened = [{r, lft} for r, lft in zip(right, left, strict=True)]
    masks = [sum(BIT[e] for e in set(o)) for o in opened]
    return stats(
        n_junctions=np.array([k if n is None else n]),
        junction_exit=pad(exits),
        junction_right=pad(right),
        junction_left=pad(left),
        junction_open=pad(masks),
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


@pytest.mark.parametrize(
    "order", ["RSL", "RLS", "SRL", "SLR", "LSR", "LRS"], ids=lambda o: f"rule-{o}"
)
def test_judging_every_rule_on_hand_made_junctions(order):
    """Each of the six orders judged on hand-made passes: at a plus crossing (all three exits
    open) its first exit, at a T without its first exit its second, where only its last is open
    that one; a pass that takes another exit is wrong."""
    from mbn.world.rules import parse_rule

    rule = parse_rule(order)
    code = {"R": R, "S": S, "L": L}
    first, second, last = (code[c] for c in order)
    plus, tee, lane = {R, S, L}, {second, last}, {last}
    right_of = {frozenset(plus): R, frozenset(tee): R if R in tee else S, frozenset(lane): last}
    left_of = {frozenset(plus): L, frozenset(tee): L if L in tee else S, frozenset(lane): last}
    sets = [plus, tee, lane]
    kw = {
        "right": [right_of[frozenset(o)] for o in sets],
        "left": [left_of[frozenset(o)] for o in sets],
        "opened": sets,
    }
    for name in (rule.name, order, order.lower()):
        spec = TrialSpec(behavior=name)
        assert spec.behavior == rule.name
        ok = judge(passes([first, second, last], **kw), spec)
        assert ok["success"].tolist() == [True] and ok["correct"].tolist() == [3]
    spec = TrialSpec(behavior=order)
    for wrong_at in range(3):
        exits = [first, second, last]
        exits[wrong_at] = next(e for e in (R, S, L, BACK) if e != exits[wrong_at])
        bad = judge(passes(exits, **kw), spec)
        assert bad["success"].tolist() == [False] and bad["correct"].tolist() == [2], wrong_at
    # a dead end (only back open) is back for every rule
    dead = judge(
        passes(
            [first, second, BACK],
            right=[*kw["right"][:2], BACK],
            left=[*kw["left"][:2], BACK],
            opened=[plus, tee, {BACK}],
        ),
        spec,
    )
    assert dead["success"].tolist() == [True]


def test_an_unknown_rule_is_one_clear_error():
    with pytest.raises(MbnInputError, match="behavior must be a rule"):
        TrialSpec(behavior="RRL")
    with pytest.raises(MbnInputError, match="behavior must be a rule"):
        TrialSpec(behavior="upward")


def test_judging_three_kinds_of_tile_by_their_rules():
    """With tile_rules (right, left, straight-right), a three-colour tile in force is judged by
    straight-right; a maze with three-colour tiles is refused under the paper's two rules."""
    spec = TrialSpec(behavior="tiles", tile_rules=("right", "left", "SRL"))
    assert spec.tile_rules == ("right", "left", "straight-right")
    plus = {R, S, L}
    kw = {"right": [R, R, R], "left": [L, L, L], "opened": [plus, plus, plus]}
    ok = judge(passes([R, L, S], tiles=[1, 2, 3], **kw), spec)
    assert ok["success"].tolist() == [True]
    bad = judge(passes([R, L, R], tiles=[1, 2, 3], **kw), spec)
    assert bad["success"].tolist() == [False] and bad["correct"].tolist() == [2]
    maze = parse_maze_text("#########\n#>.1.2.3#\n#######.#\n", "t.maze")
    with pytest.raises(MbnInputError, match="3-colour tiles"):
        TrialSpec(behavior="tiles").check_maze(maze)
    spec.check_maze(maze)
    with pytest.raises(MbnInputError, match="tile_rules"):
        TrialSpec(behavior="tiles", tile_rules=())
    with pytest.raises(MbnInputError, match="unknown rule"):
        TrialSpec(behavior="tiles", tile_rules=("right", "up"))


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
        "timed_out": np.array([False, True]),
        "correct": np.array([3, 1]),
        "judged": np.array([3, 2]),
        "stall": np.array([0.0, 0.1]),
    }
    assert summary(v) == {
        "trials": 2,
        "successes": 1,
        "success_rate": 0.5,
        "timed_out": 1,
        "junctions": 5,
        "correct_junctions": 4,
        "mean_stall_fraction": pytest.approx(0.05),
    }


def test_trials_that_run_out_of_time_are_timed_out_not_failed_by_the_controller():
    spec = TrialSpec(behavior="right")
    # two correct junctions, then the time ran out: timed out
    short = judge(passes([R, S], right=[R, S], left=[L, S]), spec)
    assert short["success"].tolist() == [False] and short["timed_out"].tolist() == [True]
    # no junction at all and no stall: timed out too
    none = judge(passes([], right=[], left=[]), spec)
    assert none["timed_out"].tolist() == [True] and none["judged"].tolist() == [0]
    # a wrong exit before the time ran out: a failure, not a time-out
    wrong = judge(passes([R, L], right=[R, S], left=[L, L]), spec)
    assert wrong["timed_out"].tolist() == [False]
    # stalled in 3 % of the whole trial (the third junction never came): a stall failure
    stalled = judge(passes([R, S], right=[R, S], left=[L, S], stall=0.03), spec)
    assert stalled["timed_out"].tolist() == [False]
    # a success is never timed out; nor is a trial whose J junctions came with a wrong exit
    ok = judge(passes([R, S, R], right=[R, S, R], left=[L, S, L]), spec)
    assert ok["success"].tolist() == [True] and ok["timed_out"].tolist() == [False]
    # with initial none only the passes after the first tile count
    tiles = TrialSpec(behavior="tiles", initial="none")
    s = passes([L, R, R], right=[R, R, R], left=[L, L, L], tiles=[0, 1, 1])
    v = judge(s, tiles)
    assert v["judged"].tolist() == [2] and v["timed_out"].tolist() == [True]
    assert summary(v)["timed_out"] == 1


def test_route_lengths_and_the_derived_time_limit():
    fig4 = builtin_maze("fig4")
    right = TrialSpec(behavior="right")
    # fig4's longest route through 3 junctions: 14.5 cells (docs: "about 17 m")
    assert longest_route(fig4, right) == pytest.approx(14.5 * 1.2)
    assert route_seconds(fig4, right) == 90.0  # 1.5 x 17.4 m / 0.3 m/s = 87 s, to 10 s
    # one junction: from the mark to the first decision cell and out of it
    assert longest_route(fig4, TrialSpec(behavior="right", junctions=1)) < 17.4
    assert route_seconds(fig4, TrialSpec(behavior="right", junctions=1)) == MIN_SECONDS
    # tiles with no rule before the first: the junctions count from it, a longer route
    tiles = TrialSpec(behavior="tiles", initial="none")
    assert longest_route(fig4, tiles) > longest_route(fig4, TrialSpec(behavior="tiles"))
    # a maze of long corridors (7.2 m between junctions) needs more than the old 60 s
    long = parse_maze_text(LONG_MAZE, "long.maze")
    assert route_seconds(long, right) > 90.0
    # the rule walk itself: a plus crossing entered from the south, right rule, one junction:
    # 3 cells to the junction's centre, half a cell out of it
    assert rule_route(crossroad("LSR"), tuple(crossroad("LSR").starts[0]), "right", 1) == (
        pytest.approx(3.5 * 1.2)
    )
    # a corridor with dead ends at both ends never meets a decision cell
    dead = parse_maze_text("#######\n#..>..#\n#######\n", "dead.maze")
    assert rule_route(dead, tuple(dead.starts[0]), "right", 1) is None
    assert route_seconds(dead, right) == MIN_SECONDS
    with pytest.raises(MbnInputError, match="junctions"):
        rule_route(dead, tuple(dead.starts[0]), "right", 0)


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


def test_trials_of_equal_controllers_compile_once():
    """Two controllers loaded from equal settings, in mazes of the same shapes, run on one
    compiled rollout (mbn.world.rollout.run_rollout); another time limit compiles another."""
    from mbn.controllers import CTRNNControllerSpec, make_controller
    from mbn.networks.ctrnn import make_ctrnn
    from mbn.world.rollout import _compiled_rollout

    rng = np.random.default_rng(0)

    def loaded():
        net = make_ctrnn(rng.normal(size=(3, 3)), np.eye(3), 0.5)
        return make_controller(CTRNNControllerSpec(net=net, behavior="right"), None)

    maze = builtin_maze("fig4")
    spec = TrialSpec(behavior="right", seconds=3.0)

    def run(c, seconds=3.0):
        return run_trial_groups(
            [maze],
            [TrialGroup("t", 0, spec, c.initial_state)],
            c.controller,
            seconds=seconds,
            dt=c.dt,
            sensors=c.sensors,
        )

    run(loaded())
    before = _compiled_rollout._cache_size()
    a, b = loaded(), loaded()
    assert a.controller is b.controller
    run(a)
    run(b)
    assert _compiled_rollout._cache_size() == before
    run(b, seconds=2.0)
    assert _compiled_rollout._cache_size() == before + 1


def test_each_pass_records_the_stretch_before_it_steps_and_stalled_moves():
    """``stretch_steps`` and ``stretch_stalls``: from the previous pass's exit (or the start)
    to this pass's, differences of the rollout's cumulative ``junction_exit_step`` and
    ``junction_stalls``; -1 where there was no pass."""
    from types import SimpleNamespace

    from mbn.experiments.trials import TrialSpec, judge

    kept = 8
    exit_step = np.full((1, kept), -1)
    stalls = np.full((1, kept), -1)
    exit_step[0, :3] = [100, 180, 300]
    stalls[0, :3] = [2, 2, 12]
    stats = SimpleNamespace(
        n_junctions=np.array([3]),
        junction_exit=np.array([[1, 1, 1] + [-1] * 5]),
        junction_open=np.array([[0b1110] * 3 + [-1] * 5]),
        junction_tile=np.zeros((1, kept), int),
        junction_exit_step=exit_step,
        junction_stalls=stalls,
        junction_cell=np.zeros((1, kept, 2), int),
        junction_heading=np.zeros((1, kept), int),
        stall_fraction=np.array([0.04]),
    )
    v = judge(stats, TrialSpec(behavior="right", junctions=3))
    np.testing.assert_array_equal(v["stretch_steps"], [[100, 80, 120]])
    np.testing.assert_array_equal(v["stretch_stalls"], [[2, 0, 10]])
    v2 = judge(stats, TrialSpec(behavior="right", junctions=4))  # a fourth pass never made
    np.testing.assert_array_equal(v2["stretch_steps"][0, 3], -1)
