"""Fidelity to Player/Stage 4.3: sonar readings and kinematics recorded from Stage itself.

Data: ``tests/data/stage/`` (copied from the project's Stage reference recordings; the arena is the
one of ``STAGE_ARENA_WALLS`` below, the robot Stage's ``pioneer3dx``).
"""

from __future__ import annotations

import csv
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.world.geometry import collides, rect_segments, sonar_ranges
from mbn.world.robot import clip_command, integrate_pose

DATA = Path(__file__).parent.parent / "data" / "stage"

#: The ten wall rectangles of the recorded arena (xmin, xmax, ymin, ymax).
STAGE_ARENA_WALLS = np.array(
    [
        [0.0, 14.0, 0.0, 1.0],
        [0.0, 4.0, 1.0, 4.6],
        [5.2, 11.8, 1.0, 4.6],
        [13.0, 14.0, 1.0, 10.4],
        [0.0, 1.0, 4.6, 10.4],
        [1.0, 4.0, 5.8, 10.4],
        [5.2, 9.4, 5.8, 10.4],
        [10.6, 13.0, 5.8, 8.2],
        [4.0, 5.2, 9.4, 10.4],
        [9.4, 13.0, 9.4, 10.4],
    ]
)


def read(name: str) -> dict[str, np.ndarray]:
    with open(DATA / name, newline="") as f:
        rows = list(csv.DictReader(f))
    return {
        k: np.array([r[k] for r in rows], dtype=object if k == "zone" else float) for k in rows[0]
    }


@pytest.fixture(scope="session")
def sonar_data():
    return read("sonar_res0.005.csv")


def test_sonar_matches_stage_at_fine_resolution(sonar_data):
    poses = np.stack([sonar_data["x"], sonar_data["y"], sonar_data["theta"]], -1)
    stage = np.stack([sonar_data[f"s{i:02d}"] for i in range(16)], -1)
    ours = np.asarray(sonar_ranges(jnp.asarray(poses), rect_segments(STAGE_ARENA_WALLS)))
    diff = np.abs(ours - stage).ravel()
    assert ours.shape == stage.shape == (len(poses), 16)
    assert np.median(diff) <= 0.005
    assert np.percentile(diff, 95) <= 0.02
    assert np.percentile(diff, 99) <= 0.05


def test_recorded_poses_are_collision_free(sonar_data):
    poses = np.stack([sonar_data["x"], sonar_data["y"], sonar_data["theta"]], -1)
    assert not np.any(np.asarray(collides(jnp.asarray(poses), STAGE_ARENA_WALLS)))


def test_kinematics_matches_stage_to_a_micrometre():
    k = read("kinematics.csv")
    runs = np.unique(k["run_id"])
    for run in runs:
        for interval in np.unique(k["interval_sim_ms"][k["run_id"] == run]):
            sel = (k["run_id"] == run) & (k["interval_sim_ms"] == interval)
            order = np.argsort(k["step"][sel])
            x, y, th = (k[c][sel][order] for c in ("x", "y", "theta"))
            v_cmd, w_cmd = k["v_cmd"][sel][0], k["w_cmd"][sel][0]
            v, w = clip_command(v_cmd, w_cmd)
            np.testing.assert_allclose(
                [float(v), float(w)],
                [k["v_actual"][sel][order][1], k["w_actual"][sel][order][1]],
                atol=1e-6,
            )
            dt = interval / 1000.0

            def step(pose, _, v=v, w=w, dt=dt):
                pose = integrate_pose(pose, v, w, dt)
                return pose, pose

            start = jnp.array([x[0], y[0], th[0]], jnp.float64)
            _, poses = jax.lax.scan(step, start, None, length=len(x) - 1)
            poses = np.asarray(poses)
            np.testing.assert_allclose(poses[:, 0], x[1:], atol=1e-6)
            np.testing.assert_allclose(poses[:, 1], y[1:], atol=1e-6)
            dth = np.angle(np.exp(1j * (poses[:, 2] - th[1:])))  # wrapped difference
            assert np.all(np.abs(dth) <= 1e-6), (run, interval)


def test_rollout_engine_sonar_matches_stage_at_fine_resolution(sonar_data):
    """The lattice engine the rollouts use, on the built-in arena, meets the same targets."""
    from mbn.world.engine import cast, compile_mazes, maze_constants, window_words
    from mbn.world.geometry import sonar_rays
    from mbn.world.mazes.builtin import stage_arena

    arena = stage_arena()
    np.testing.assert_array_equal(np.sort(arena.walls, 0), np.sort(STAGE_ARENA_WALLS, 0))
    world = compile_mazes([arena])
    poses = jnp.asarray(np.stack([sonar_data["x"], sonar_data["y"], sonar_data["theta"]], -1))

    @jax.jit
    def read(p):
        mc = maze_constants(world, jnp.zeros(p.shape[0], jnp.int32))
        words, ci, cj = window_words(world, mc, p[:, 0], p[:, 1])
        o, a = sonar_rays(p)
        return cast(world, mc, words, ci, cj, o[..., 0], o[..., 1], a)

    ours = np.asarray(read(poses))
    stage = np.stack([sonar_data[f"s{i:02d}"] for i in range(16)], -1)
    diff = np.abs(ours - stage).ravel()
    assert np.median(diff) <= 0.005
    assert np.percentile(diff, 95) <= 0.02
    assert np.percentile(diff, 99) <= 0.05
