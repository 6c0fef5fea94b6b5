"""The Gymnasium environment: API conformance, seeding, and the world's rules for one robot."""

from __future__ import annotations

import importlib
import math
import subprocess
import sys
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

from gymnasium.utils.env_checker import check_env  # noqa: E402

from mbn.errors import MbnInputError  # noqa: E402
from mbn.world.engine import (  # noqa: E402
    cast,
    compile_mazes,
    maze_constants,
    window_words,
)
from mbn.world.geometry import rect_segments, sonar_ranges, sonar_rays  # noqa: E402
from mbn.world.gym_env import ENV_ID, PioneerMazeEnv, register  # noqa: E402
from mbn.world.mazes.model import Maze, Tile, merge_cells  # noqa: E402
from mbn.world.robot import SONAR_POSES  # noqa: E402

CELL = 1.2


@pytest.fixture(scope="session")
def corridor() -> Maze:
    """A corridor along x: free for x in [1.2, 14.4], y in [1.2, 2.4]; a two-colour tile across
    it at x = 6."""
    grid = np.array([list("#############"), list("#...........#"), list("#############")])
    return Maze(
        name="corridor",
        walls=merge_cells(grid == "#", CELL),
        bounds=(0.0, 13 * CELL, 0.0, 3 * CELL),
        tiles=(Tile(6.0, 1.8, 2, heading=0.0),),
        starts=[[2.0, 1.8, 0.0], [14.15, 1.8, 0.0]],
    )


def record_warnings(fn) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fn()
    return [str(w.message) for w in caught]


def test_check_env_passes(corridor):
    env = PioneerMazeEnv(corridor, normalized_actions=True)
    msgs = record_warnings(lambda: check_env(env))
    # a directly constructed environment has no spec to re-make it in other render modes
    assert all("not having a spec" in m for m in msgs), msgs
    # made through the registry (spec set): the unwrapped environment raises no warning at all
    made = gymnasium.make(ENV_ID, maze=corridor, normalized_actions=True)
    assert record_warnings(lambda: check_env(made.unwrapped)) == []
    # the default physical action space (v in m/s, w in rad/s) and the wrapped environment
    # draw Gymnasium's advice to normalise actions and to check the unwrapped environment
    msgs = record_warnings(lambda: check_env(gymnasium.make(ENV_ID)))
    assert msgs and all(
        "normalized space" in m or "different from the unwrapped" in m for m in msgs
    ), msgs


def test_make_and_register(corridor):
    register()  # idempotent
    register()
    env = gymnasium.make(ENV_ID, maze=corridor, jitter=False)
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert obs.dtype == np.float32 and obs.shape == (17,)
    np.testing.assert_allclose(info["pose"], corridor.starts[0])
    assert env.action_space.shape == (2,)
    np.testing.assert_allclose(env.action_space.high, [0.5, math.pi / 2], rtol=1e-6)
    obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs) and not terminated and not truncated
    env.close()


def test_reset_with_a_seed_is_deterministic(corridor):
    env = PioneerMazeEnv(corridor)
    a, ia = env.reset(seed=7)
    b, ib = env.reset(seed=7)
    _, ic = env.reset(seed=8)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(ia["pose"], ib["pose"])
    assert not np.array_equal(ia["pose"], ic["pose"])
    # the jitter stays within 0.1 m along / across the heading and 5 degrees
    d = ia["pose"] - corridor.starts[0]
    assert abs(d[0]) <= 0.1 + 1e-12 and abs(d[1]) <= 0.1 + 1e-12
    assert abs(d[2]) <= math.radians(5) + 1e-12


def test_a_step_moves_by_v_dt_along_the_heading(corridor):
    env = PioneerMazeEnv(corridor, jitter=False)
    start = np.array([4.0, 1.8, 0.3])
    env.reset(options={"start": start})
    obs, reward, *_, info = env.step(np.array([0.3, 0.5], np.float32))
    v, w = float(np.float32(0.3)), float(np.float32(0.5))
    expected = start + np.array([v * 0.1 * math.cos(0.3), v * 0.1 * math.sin(0.3), w * 0.1])
    np.testing.assert_allclose(info["pose"], expected, atol=1e-6)
    assert not info["stalled"]
    assert info["v"] == pytest.approx(v) and info["w"] == pytest.approx(w)
    clear = min(1.0, float(obs[:16].min()) / 0.5)
    assert reward == pytest.approx((v / 0.5) * (1 - w / (math.pi / 2)) * clear, rel=1e-5)
    # commands beyond the limits are clipped like Stage's
    obs, reward, *_, info = env.step(np.array([2.0, -9.0]))
    assert info["v"] == pytest.approx(0.5) and info["w"] == pytest.approx(-math.pi / 2)
    # normalised actions scale [-1, 1] to the limits
    env = PioneerMazeEnv(corridor, jitter=False, normalized_actions=True)
    env.reset(options={"start": start})
    *_, info = env.step(np.array([0.5, -0.5]))
    assert info["v"] == pytest.approx(0.25) and info["w"] == pytest.approx(-math.pi / 4)


def test_driving_into_a_wall_stalls_and_the_pose_stays(corridor):
    env = PioneerMazeEnv(corridor, start=1, jitter=False)  # nose 4 cm from the east wall
    obs0, info0 = env.reset()
    obs, reward, terminated, _, info = env.step([0.5, 0.0])
    assert info["stalled"] and reward == -1.0
    np.testing.assert_array_equal(info["pose"], info0["pose"])
    np.testing.assert_array_equal(obs, obs0)
    assert info["v"] == 0.0 and not terminated
    # backing away is allowed
    *_, info = env.step([-0.5, 0.0])
    assert not info["stalled"]
    assert info["pose"][0] == pytest.approx(14.15 - 0.05)


def test_observation_is_the_engines_cast(corridor):
    env = PioneerMazeEnv(corridor, jitter=False)
    world = compile_mazes([corridor])
    mc = maze_constants(world, jnp.zeros((1,), jnp.int32))
    segments = rect_segments(corridor.solid_rects())

    @jax.jit
    def engine_ranges(p):
        words, ci, cj = window_words(world, mc, p[:, 0], p[:, 1])
        origins, angles = sonar_rays(p, SONAR_POSES)
        return cast(world, mc, words, ci, cj, origins[..., 0], origins[..., 1], angles)[0]

    for pose in ([2.0, 1.8, 0.0], [5.3, 1.5, 2.4], [9.0, 1.9, -0.4]):
        obs, _ = env.reset(options={"start": pose})
        p = jnp.asarray([pose])
        expected = np.asarray(engine_ranges(p))
        np.testing.assert_allclose(obs[:16], expected, rtol=1e-6, atol=1e-6)
        exact = np.asarray(sonar_ranges(p[0], segments))  # exact geometry agrees too
        np.testing.assert_allclose(obs[:16], exact, atol=1e-5)


def test_camera_blobs_and_tile_in_force(corridor):
    env = PioneerMazeEnv(corridor, jitter=False, max_steps=40)
    obs, info = env.reset(options={"start": [4.8, 1.8, 0.0]})  # the tile 1.2 m ahead
    assert obs[16] == 2.0 and info["camera"] == 2 and info["tile"] == 0
    tiles = []
    for _ in range(40):
        obs, _, terminated, truncated, info = env.step([0.5, 0.0])
        tiles.append(info["tile"])
    assert truncated and not terminated
    assert tiles[0] == 0 and tiles[-1] == 2  # driven over: the tile stays in force
    assert obs[16] == 0.0 and info["camera"] == 0  # behind the robot now
    off = PioneerMazeEnv(corridor, jitter=False, camera=None)
    obs, info = off.reset(options={"start": [4.8, 1.8, 0.0]})
    assert obs[16] == 0.0 and info["camera"] == 0


def test_rgb_array_render(corridor):
    env = PioneerMazeEnv(corridor, render_mode="rgb_array")
    env.reset(seed=1)
    a = env.render()
    env.step([0.5, 0.3])
    b = env.render()
    assert isinstance(a, np.ndarray) and a.dtype == np.uint8 and a.ndim == 3
    assert a.shape == b.shape and a.shape[2] == 3 and np.any(a != b)
    env.close()
    env.close()
    assert PioneerMazeEnv(corridor).render() is None


def test_bad_arguments_are_one_line_errors(corridor):
    with pytest.raises(MbnInputError, match="in a wall"):
        PioneerMazeEnv(corridor, start=[0.5, 0.5, 0.0])
    with pytest.raises(MbnInputError, match="out of range"):
        PioneerMazeEnv(corridor, start=5)
    with pytest.raises(MbnInputError, match="render_mode"):
        PioneerMazeEnv(corridor, render_mode="human")
    env = PioneerMazeEnv(corridor)
    env.reset(seed=0)
    with pytest.raises(MbnInputError, match="action"):
        env.step([0.1, 0.2, 0.3])
    with pytest.raises(MbnInputError, match="unknown reset option"):
        env.reset(options={"strat": 0})


def test_without_gymnasium_the_import_error_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "gymnasium", None)
    monkeypatch.delitem(sys.modules, "mbn.world.gym_env")
    with pytest.raises(ImportError, match=r"pip install 'mbn\[gym\]'"):
        importlib.import_module("mbn.world.gym_env")


def test_importing_mbn_does_not_import_gymnasium():
    code = (
        "import sys, mbn, mbn.world, mbn.viz.animate, mbn.world.rollout;"
        " assert 'gymnasium' not in sys.modules, 'gymnasium imported'"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.mark.slow  # CI's wheel check makes the environment so, from the wheel
def test_gymnasium_make_works_in_a_fresh_interpreter_with_no_import_of_mbn():
    # the installed path file registers the environment when gymnasium is imported (docs/gym.md)
    code = (
        "import sys, gymnasium\n"
        "assert 'mbn' not in sys.modules and 'jax' not in sys.modules, 'imported at start-up'\n"
        f"assert {ENV_ID!r} in gymnasium.registry, 'not registered'\n"
        f"env = gymnasium.make({ENV_ID!r}, maze='cross_LSR', jitter=False)\n"
        "obs, info = env.reset(seed=0)\n"
        "assert obs.shape == (17,) and 'mbn.world.gym_env' in sys.modules\n"
        "print('made')\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=False, timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "made"


def test_the_start_up_hook_registers_the_id_and_entry_point_of_the_environment():
    import _mbn_gymnasium

    assert _mbn_gymnasium.ENV_ID == ENV_ID
    module, name = _mbn_gymnasium.ENTRY_POINT.split(":")
    assert getattr(importlib.import_module(module), name) is PioneerMazeEnv
    assert gymnasium.registry[ENV_ID].entry_point == _mbn_gymnasium.ENTRY_POINT
