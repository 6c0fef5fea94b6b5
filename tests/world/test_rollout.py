"""Batched rollouts: Stage kinematics, the stall rule, junctions, tiles, noise and batching."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import jax
import jax.experimental
import jax.numpy as jnp
import numpy as np
import pytest

from mbn import paper
from mbn.control.ctrnn import CTRNNState, ctrnn_controller, initial_state
from mbn.errors import MbnInputError
from mbn.networks.ctrnn import make_ctrnn
from mbn.precision import scope
from mbn.world.engine import CameraConfig, compile_mazes, march_steps
from mbn.world.geometry import collides
from mbn.world.junctions import junction_sequence
from mbn.world.mazes.builtin import crossroad
from mbn.world.mazes.model import Maze
from mbn.world.rollout import (
    EXIT_NAMES,
    RolloutConfig,
    Shared,
    concatenate_states,
    input_reach,
    junction_arrays,
    rollout,
)
from mbn.world.sensors import ALL_SONARS, NoiseConfig, SensorConfig

DATA = Path(__file__).parent.parent / "data" / "stage"


def scripted(state, obs):
    """Controller replaying a per-step command table: state = (step, table (T, 2))."""
    step, table = state
    v, w = table[step, 0], table[step, 1]
    return (step + 1, table), (v, w)


def script_state(tables: np.ndarray, dtype=jnp.float32):
    tables = jnp.asarray(tables, dtype)
    return (jnp.zeros(tables.shape[0], jnp.int32), tables)


def run(mazes, tables, poses, maze_index=None, dtype=jnp.float32, **config):
    world = compile_mazes(mazes)
    junctions = junction_arrays(mazes, world)
    cfg = RolloutConfig(**config)
    maze_index = np.zeros(len(poses), np.int32) if maze_index is None else maze_index
    fn = jax.jit(
        lambda s, p, m, k: rollout(world, scripted, s, p, m, cfg, junctions=junctions, key=k)
    )
    return fn(
        script_state(tables, dtype),
        jnp.asarray(poses, dtype),
        jnp.asarray(maze_index),
        jax.random.key(0),
    )


def test_constant_command_reproduces_stage_kinematics():
    """In an empty world, the rollout's poses are Stage's (kinematics.csv, 100 ms runs)."""
    with open(DATA / "kinematics.csv", newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["interval_sim_ms"] == "100"]
    runs = sorted({r["run_id"] for r in rows})
    empty = Maze(
        "empty",
        walls=[[100.0, 101.0, 100.0, 101.0]],
        bounds=(-20, 101, -20, 101),
        outside_is_wall=False,
    )
    tables, starts, expected = [], [], []
    for run_id in runs:
        sel = sorted((r for r in rows if r["run_id"] == run_id), key=lambda r: int(r["step"]))
        tables.append([[float(sel[0]["v_cmd"]), float(sel[0]["w_cmd"])]] * 50)
        starts.append([float(sel[0][c]) for c in ("x", "y", "theta")])
        expected.append([[float(r[c]) for c in ("x", "y", "theta")] for r in sel[:50]])
    out = run(
        [empty], np.array(tables), np.array(starts), dtype=jnp.float64, steps=50, record_every=1
    )  # float64: the tests run with jax_enable_x64
    poses = np.asarray(out.trajectory.pose)
    expected = np.array(expected)
    assert poses.shape == expected.shape
    np.testing.assert_allclose(poses[..., :2], expected[..., :2], atol=1e-6)
    dth = np.angle(np.exp(1j * (poses[..., 2] - expected[..., 2])))
    assert np.max(np.abs(dth)) < 1e-6


def test_a_colliding_move_is_undone_and_counted_as_a_stall():
    maze = crossroad("S")  # a straight corridor: the robot drives north into the far wall
    table = np.tile([[0.5, 0.0]], (400, 1))
    out = run([maze], table[None], maze.starts[:1], steps=400, record_every=1)
    poses = np.asarray(out.trajectory.pose[0])
    stalled = np.asarray(out.trajectory.stalled[0])
    assert not np.any(np.asarray(collides(jnp.asarray(poses), maze.solid_rects())))
    first = int(np.argmax(stalled))  # stalled[t]: the move towards sample t was undone
    assert first > 0 and np.all(stalled[first:])  # once at the wall, every move is undone
    np.testing.assert_array_equal(
        poses[first - 1 :], np.broadcast_to(poses[first], (400 - first + 1, 3))
    )
    # the front of the body (x 0.21085 ahead of the pose) stops within one move of the wall
    gap = maze.bounds[3] - (poses[first, 1] + 0.21085)
    assert 0.0 <= gap < 0.05 + 1e-6
    stats = out.stats
    assert float(stats.stall_fraction[0]) == pytest.approx((400 - first + 1) / 400, abs=1.5e-2)
    assert float(stats.distance[0]) == pytest.approx(poses[first, 1] - poses[0, 1], abs=1e-4)


def _turn_table(turn: str, steps: int = 200) -> np.ndarray:
    """Drive 3.6 m north to the junction centre, turn 90 degrees, drive on."""
    table = np.zeros((steps, 2))
    table[:, 0] = 0.5
    table[:72, 0] = 0.5  # 72 x 5 cm = 3.6 m: from the south start to the junction centre
    if turn != "straight":
        table[72:82, 0] = 0.0
        table[72:82, 1] = (math.pi / 2) * (1 if turn == "left" else -1)
    return table


@pytest.mark.parametrize("turn", ["left", "straight", "right"])
def test_junction_pass_is_tracked_like_the_trajectory_analysis(turn):
    maze = crossroad("LSR")
    out = run([maze], _turn_table(turn)[None], maze.starts[:1], steps=200, record_every=1)
    s = out.stats
    assert int(s.n_junctions[0]) == 1
    assert EXIT_NAMES[int(s.junction_exit[0, 0])] == turn
    assert EXIT_NAMES[int(s.junction_right[0, 0])] == "right"
    assert EXIT_NAMES[int(s.junction_left[0, 0])] == "left"
    assert int(s.junction_heading[0, 0]) == 0  # entered moving north
    assert tuple(np.asarray(s.junction_cell[0, 0])) == (3, 3)
    passes = junction_sequence(maze, np.asarray(out.trajectory.pose[0]))
    assert [p.exit for p in passes] == [turn]
    assert passes[0].step_in == int(s.junction_step[0, 0])
    assert passes[0].step_out == int(s.junction_exit_step[0, 0])
    assert int(s.junction_stalls[0, 0]) == 0


def _plus_of_widths(dx: float, dy: float) -> Maze:
    """A plus crossing of 1.2 m corridors whose arms are 3.7 m long (not a whole number of
    corridor widths: a grid of columns and rows of their own widths), its south-west corner at
    ``(dx, dy)``; one start 3.62 m south of the junction's centre and 13 mm east of it, facing
    north (no move of 5 cm from it ends on a cell's border, where float32 rounding would decide
    the step of a pass)."""
    from mbn.world.mazes.gridify import as_grid_maze

    a, w = 3.7, 1.2
    size = 2 * a + w
    blocks = [[0.0, a, 0.0, a], [a + w, size, 0.0, a], [0.0, a, a + w, size]]
    blocks.append([a + w, size, a + w, size])
    shift = np.array([dx, dx, dy, dy])
    maze = Maze(
        "plus",
        walls=np.array(blocks) + shift,
        bounds=tuple(np.array([0.0, size, 0.0, size]) + shift),
        starts=[[dx + a + w / 2 + 0.013, dy + a + w / 2 - 3.62, math.pi / 2]],
    )
    return as_grid_maze(maze)


@pytest.mark.parametrize("turn", [pytest.param("left", marks=pytest.mark.slow), "right"])
def test_a_grid_of_several_widths_is_tracked_like_the_trajectory_analysis_wherever_it_lies(turn):
    """A robot in the plus crossing of 3.7 m arms (at the origin and far from it) and one in the
    built-in crossroad, in one batch, make the same pass, as the trajectory analysis sees it."""
    mazes = [_plus_of_widths(0.0, 0.0), _plus_of_widths(-20.3, -7.7), crossroad("LSR")]
    assert [m.cell for m in mazes] == [None, None, pytest.approx(1.2)]
    poses = np.concatenate([m.starts[:1] for m in mazes])
    tables = np.stack([_turn_table(turn)] * 3)
    out = run(mazes, tables, poses, np.arange(3), steps=200, record_every=1)
    s = out.stats
    for k, maze in enumerate(mazes):
        assert int(s.n_junctions[k]) == 1
        assert EXIT_NAMES[int(s.junction_exit[k, 0])] == turn
        assert EXIT_NAMES[int(s.junction_right[k, 0])] == "right"
        assert EXIT_NAMES[int(s.junction_left[k, 0])] == "left"
        assert int(s.junction_heading[k, 0]) == 0
        passes = junction_sequence(maze, np.asarray(out.trajectory.pose[k]))
        assert [(p.exit, p.cell) for p in passes] == [
            (turn, tuple(int(v) for v in np.asarray(s.junction_cell[k, 0])))
        ]
        assert passes[0].step_in == int(s.junction_step[k, 0])
        assert passes[0].step_out == int(s.junction_exit_step[k, 0])
    assert tuple(np.asarray(s.junction_cell[0, 0])) == (1, 1)  # the middle of 3 x 3 cells
    # a pure translation: the two plus crossings' passes are the same, step for step
    for name in ("junction_cell", "junction_step", "junction_exit_step", "junction_exit"):
        np.testing.assert_array_equal(np.asarray(getattr(s, name))[0], getattr(s, name)[1])


def test_rule_exits_depend_on_the_crossroad_kind():
    kinds = ["LS", "SR", "LR"]
    mazes = [crossroad(k) for k in kinds]
    tables = np.stack([_turn_table(t) for t in ("left", "right", "left")])
    poses = np.stack([m.starts[0] for m in mazes])
    out = run(mazes, tables, poses, maze_index=np.arange(3), steps=200)
    right = [EXIT_NAMES[int(x)] for x in out.stats.junction_right[:, 0]]
    left = [EXIT_NAMES[int(x)] for x in out.stats.junction_left[:, 0]]
    assert right == ["straight", "right", "right"]
    assert left == ["left", "straight", "left"]
    # the open exits recorded give every rule's exit; the right and left rules' agree with
    # the exits recorded for them
    from mbn.world.rules import rule_exit_codes

    mask = np.asarray(out.stats.junction_open[:, 0])
    np.testing.assert_array_equal(rule_exit_codes("right", mask), out.stats.junction_right[:, 0])
    np.testing.assert_array_equal(rule_exit_codes("left", mask), out.stats.junction_left[:, 0])
    straight_right = [EXIT_NAMES[int(x)] for x in rule_exit_codes("straight-right", mask)]
    straight_left = [EXIT_NAMES[int(x)] for x in rule_exit_codes("SLR", mask)]
    assert straight_right == ["straight", "straight", "right"]
    assert straight_left == ["straight", "straight", "left"]
    # no pass beyond the first: no mask
    assert np.all(np.asarray(out.stats.junction_open[:, 1]) == -1)


def test_tile_driven_over_stays_in_force_and_camera_sees_it_ahead():
    maze = crossroad("S", tile=2)
    table = np.tile([[0.5, 0.0]], (60, 1))
    out = run([maze], table[None], maze.starts[:1], steps=60, record_every=1, camera=CameraConfig())
    tr = out.trajectory
    y = np.asarray(tr.pose[0, :, 1])
    tile_y = maze.tiles[0].y
    cam = np.asarray(tr.camera[0])
    tile = np.asarray(tr.tile[0])
    assert cam[0] == 2  # 1.2 m ahead at the start
    over = y + math.cos(0.0) * (-0.04465) >= tile_y - 0.15
    assert np.all(tile[over] == 2) and np.all(tile[~over] == 0)
    assert int(out.stats.tile[0]) == 2
    assert cam[-1] == 0  # passed: behind the camera


def test_noise_is_seeded_and_off_by_default():
    maze = crossroad("LSR")
    mazes = [maze]
    world = compile_mazes(mazes)
    net = make_ctrnn(np.full((2, 3, 3), 2.0), np.full((2, 3, 3), 3.0), 0.5, dtype=np.float32)
    ctrl = ctrnn_controller()
    poses = jnp.asarray(np.repeat(maze.starts[:1], 2, 0), jnp.float32)
    mi = jnp.zeros(2, jnp.int32)

    compiled = {}

    def go(noise, key):
        if noise not in compiled:
            cfg = RolloutConfig(steps=50, noise=noise)
            compiled[noise] = jax.jit(
                lambda k: rollout(world, ctrl, initial_state(net), poses, mi, cfg, key=k)
            )
        return np.asarray(compiled[noise](key).stats.final_pose)

    plain = go(NoiseConfig(), None)
    np.testing.assert_array_equal(plain[0], plain[1])
    noisy = NoiseConfig(sonar_std=0.02, v_std=0.05, w_std=0.1)
    a, b = go(noisy, jax.random.key(1)), go(noisy, jax.random.key(1))
    c = go(noisy, jax.random.key(2))
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    assert not np.allclose(a[0], a[1])  # each robot gets its own noise
    with pytest.raises(MbnInputError, match="key"):
        go(noisy, None)


def test_batch_composition_and_recording_do_not_change_episodes():
    mazes = [crossroad(k) for k in ("L", "SR")]
    world = compile_mazes(mazes)
    rng = np.random.default_rng(0)
    net = make_ctrnn(
        rng.uniform(-8, 8, (6, 3, 3)), rng.uniform(-8, 8, (6, 3, 3)), 0.5, dtype=np.float32
    )
    ctrl = ctrnn_controller()
    poses = jnp.asarray(np.stack([mazes[i % 2].starts[0] for i in range(6)]), jnp.float32)
    mi = jnp.asarray(np.arange(6) % 2)
    full = jax.jit(
        lambda s: rollout(world, ctrl, s, poses, mi, RolloutConfig(steps=80, record_every=7))
    )(initial_state(net))
    one = jax.jit(lambda s: rollout(world, ctrl, s, poses[3:4], mi[3:4], RolloutConfig(steps=80)))(
        initial_state(jax.tree.map(lambda a: a[3:4], net))
    )
    for a, b in zip(jax.tree.leaves(full.stats), jax.tree.leaves(one.stats), strict=True):
        np.testing.assert_allclose(np.asarray(a)[3:4], np.asarray(b), rtol=1e-6, atol=1e-6)
    assert full.trajectory.pose.shape == (6, 11, 3)
    np.testing.assert_allclose(full.trajectory.t, np.arange(11) * 0.7, atol=1e-6)


def test_sonar_choice_and_bad_config():
    maze = crossroad("LSR")
    out = run(
        [maze],
        np.zeros((1, 10, 2)),
        maze.starts[:1],
        steps=10,
        record_every=1,
        sensors=SensorConfig(sonars=ALL_SONARS),
    )
    assert out.trajectory.ranges.shape == (1, 10, 16)
    assert out.stats.S_mean.shape == (1, 16)
    with pytest.raises(MbnInputError, match="steps"):
        RolloutConfig(steps=0)
    with pytest.raises(MbnInputError, match="near"):
        SensorConfig(near=2.0, far=1.0)
    with pytest.raises(MbnInputError, match="repeat"):
        SensorConfig(sonars=(1, 1))


@pytest.mark.slow  # the reach read exactly: test_step
def test_a_sonar_reach_at_the_inputs_far_changes_no_episode():
    """Casting the sonars only as far as the inputs read them (``input_reach``) leaves every
    episode and every statistic a fitness reads bit for bit as it was, in float32 as the
    experiment runs: the poses, the junction exits, S, and the shortest range clipped at far."""
    mazes = [crossroad(k) for k in ("LSR", "SR", "L")]
    world = compile_mazes(mazes)
    junctions = junction_arrays(mazes, world)
    rng = np.random.default_rng(3)
    n = 24
    net = make_ctrnn(
        rng.uniform(-20, 20, (n, 3, 3)), rng.uniform(-20, 20, (n, 3, 3)), 0.5, dtype=np.float32
    )
    mi = jnp.asarray(np.arange(n) % 3)
    poses = jnp.asarray(np.stack([mazes[i % 3].starts[0] for i in range(n)]), jnp.float32)
    sensors = SensorConfig()
    reach = input_reach(sensors, NoiseConfig())
    assert reach == sensors.far == 2.0
    assert march_steps(world, reach) < world.n_march  # it does shorten the rays
    out = {}
    for r in (None, reach):
        cfg = RolloutConfig(steps=150, sonar_reach=r)
        out[r] = jax.jit(
            lambda s, cfg=cfg: rollout(
                world, ctrnn_controller(), s, poses, mi, cfg, junctions=junctions
            )
        )(initial_state(net)).stats
    a, b = out[None], out[reach]
    for name in ("final_pose", "S_mean", "junction_exit", "stall_fraction", "mean_v"):
        np.testing.assert_array_equal(np.asarray(getattr(a, name)), np.asarray(getattr(b, name)))
    np.testing.assert_array_equal(
        np.minimum(np.asarray(a.min_range), 2.0), np.minimum(np.asarray(b.min_range), 2.0)
    )
    assert len(np.unique(np.asarray(a.final_pose)[:, 0])) > n // 2  # the robots went places
    # where S is read otherwise, the reach is the whole range
    assert input_reach(SensorConfig(normalization="metres"), NoiseConfig()) is None
    assert input_reach(sensors, NoiseConfig(sonar_std=0.02)) is None
    assert input_reach(sensors, NoiseConfig(sonar_dropout=0.1, wheel_std=0.05)) == 2.0
    for bad in (0.0, -1.0, 5.5):
        with pytest.raises(MbnInputError, match="sonar_reach"):
            RolloutConfig(sonar_reach=bad)


from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_PROPERTY_MAZES = [crossroad("LSR"), crossroad("LR")]
_PROPERTY_WORLD = compile_mazes(_PROPERTY_MAZES)
_PROPERTY_RUN = jax.jit(
    lambda s, p, m: rollout(
        _PROPERTY_WORLD, ctrnn_controller(), s, p, m, RolloutConfig(steps=120, record_every=1)
    )
)


@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), scale=st.floats(1.0, 40.0))
def test_no_step_ends_inside_a_wall(seed, scale):
    """Random controllers driving hard at walls: every pose of every episode is free."""
    rng = np.random.default_rng(seed)
    n = 8
    net = make_ctrnn(
        rng.uniform(-scale, scale, (n, 3, 3)),
        rng.uniform(-scale, scale, (n, 3, 3)),
        0.5,
        dtype=np.float32,
    )
    mi = np.arange(n) % 2
    jitter = rng.uniform([-0.3, 0.0, -0.5], [0.3, 2.0, 0.5], (n, 3))
    poses = np.stack([_PROPERTY_MAZES[m].starts[0] for m in mi]) + jitter
    out = _PROPERTY_RUN(initial_state(net), jnp.asarray(poses, jnp.float32), jnp.asarray(mi))
    traj = np.asarray(out.trajectory.pose)
    for m in (0, 1):
        inside = collides(
            jnp.asarray(traj[mi == m].reshape(-1, 3)), _PROPERTY_MAZES[m].solid_rects()
        )
        assert not np.any(np.asarray(inside))
    ranges = np.asarray(out.trajectory.ranges)
    assert ranges.min() >= 0.0 and ranges.max() <= 5.0


def test_episode_batch_is_every_controller_times_every_start():
    from mbn.world.mazes.builtin import builtin_maze
    from mbn.world.rollout import episode_batch

    mazes = [crossroad("L"), builtin_maze("fig4")]
    ctrl, poses, mi = episode_batch(mazes, 3)
    n = 1 + len(mazes[1].starts)
    assert len(ctrl) == len(poses) == len(mi) == 3 * n
    assert ctrl.tolist() == [0] * n + [1] * n + [2] * n
    np.testing.assert_array_equal(
        poses[n : 2 * n], np.concatenate([mazes[0].starts, mazes[1].starts])
    )
    assert mi[:n].tolist() == [0] + [1] * (n - 1)
    c1, p1, m1 = episode_batch(mazes, 2, first_start_only=True)
    np.testing.assert_array_equal(p1[1], mazes[1].starts[0])
    assert c1.tolist() == [0, 0, 1, 1] and m1.tolist() == [0, 1, 0, 1]
    with pytest.raises(MbnInputError, match="n_controllers"):
        episode_batch(mazes, 0)


def _interpreter_net():
    from mbn.networks.multiplier import load_default
    from mbn.networks.programmable import build_interpreter, differing_connections

    rng = np.random.default_rng(4)
    rf = make_ctrnn(rng.uniform(-8, 8, (3, 3)), rng.uniform(-8, 8, (3, 3)), 0.5)
    W, WE = np.array(rf.W), np.array(rf.WE)
    W[1, 2] += 4.0
    WE[1, 0] -= 3.0
    lf = make_ctrnn(W, WE, 0.5)
    return build_interpreter(rf, differing_connections(rf, lf, margin=0.0), load_default(6)).net


@pytest.mark.parametrize("kind", [pytest.param("follower", marks=pytest.mark.slow), "interpreter"])
def test_a_shared_network_drives_as_a_batched_copy_of_it(kind):
    """A network held once for the batch (:class:`Shared`) gives the episodes that a copy of it
    per robot gives (float64: the same up to the order of the sums)."""
    with scope("float64"):
        if kind == "follower":
            net = make_ctrnn(np.array(paper.W_RF) / 20, np.array(paper.WE_RF) / 20, 0.5)
        else:
            net = _interpreter_net()
        n_in = net.num_inputs
        ctrl = ctrnn_controller(
            substeps=20, inputs=lambda obs: jnp.concatenate([obs.inputs, jnp.full(n_in - 3, 0.3)])
        )
        mazes = [crossroad(k) for k in ("L", "SR", "LSR")]
        world = compile_mazes(mazes)
        poses = jnp.asarray(np.stack([mazes[i % 3].starts[0] for i in range(6)]))
        mi = jnp.asarray(np.arange(6) % 3)
        y = jnp.zeros((6, net.num_neurons))
        cfg = RolloutConfig(steps=120)
        go = jax.jit(lambda s: rollout(world, ctrl, s, poses, mi, cfg))
        shared = go(CTRNNState(Shared(net), y))
        copies = go(CTRNNState(jax.tree.map(lambda a: jnp.broadcast_to(a, (6, *a.shape)), net), y))
        np.testing.assert_allclose(
            np.asarray(shared.stats.final_pose), np.asarray(copies.stats.final_pose), atol=1e-9
        )
        assert isinstance(shared.controller_state.net, Shared)
        np.testing.assert_allclose(
            np.asarray(shared.controller_state.y), np.asarray(copies.controller_state.y), atol=1e-9
        )


def test_concatenated_states_keep_one_shared_network_and_batch_different_ones():
    a = make_ctrnn(np.eye(3), np.zeros((3, 3)), 0.5)
    b = make_ctrnn(2 * np.eye(3), np.zeros((3, 3)), 0.5)
    y2, y3 = jnp.zeros((2, 3)), jnp.ones((3, 3))
    same = concatenate_states([CTRNNState(Shared(a), y2), CTRNNState(Shared(a), y3)], [2, 3])
    assert isinstance(same.net, Shared) and same.y.shape == (5, 3)
    mixed = concatenate_states([CTRNNState(Shared(a), y2), CTRNNState(Shared(b), y3)], [2, 3])
    assert not isinstance(mixed.net, Shared)
    assert mixed.net.W.shape == (5, 3, 3)
    np.testing.assert_array_equal(
        np.asarray(mixed.net.W[:2]), np.broadcast_to(np.eye(3), (2, 3, 3))
    )
    np.testing.assert_array_equal(
        np.asarray(mixed.net.W[2:]), np.broadcast_to(2 * np.eye(3), (3, 3, 3))
    )
    with pytest.raises(MbnInputError):
        concatenate_states([CTRNNState(Shared(a), y2)], [2, 3])


def test_a_recorded_controller_state_leaves_out_the_shared_network():
    net = make_ctrnn(np.array(paper.W_RF) / 20, np.array(paper.WE_RF) / 20, 0.5, dtype=np.float32)
    maze = crossroad("LSR")
    world = compile_mazes([maze])
    poses = jnp.asarray(np.stack([maze.starts[0]] * 2), jnp.float32)
    cfg = RolloutConfig(steps=20, record_every=5, record_controller=True)
    out = jax.jit(lambda s: rollout(world, ctrnn_controller(), s, poses, jnp.zeros(2, int), cfg))(
        CTRNNState(Shared(net), jnp.zeros((2, 3), jnp.float32))
    )
    assert out.trajectory.controller.net is None
    assert out.trajectory.controller.y.shape == (2, 4, 3)
