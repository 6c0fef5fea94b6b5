"""Pictures of episodes: paths, footprints, stalls and sonar rays where the robot was."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.viz.episodes import EpisodeView, draw_trajectory, plot_episodes
from mbn.viz.maze import draw_maze
from mbn.world.engine import compile_mazes
from mbn.world.geometry import body_polygon, sonar_rays
from mbn.world.robot import SONAR_POSES
from mbn.world.rollout import RolloutConfig, Trajectory, rollout
from mbn.world.sensors import ALL_SONARS, SensorConfig


def test_draw_trajectory_coordinates(corridor, tmp_path):
    n = 21
    poses = np.stack([np.linspace(2.0, 6.0, n), np.full(n, 1.8), np.linspace(0.0, 0.3, n)], axis=-1)
    ranges = np.full((n, 16), 0.5)
    ranges[:, 3] = 5.0  # one ray reads the maximum: drawn dotted
    stalled = np.zeros(n, dtype=bool)
    stalled[[4, 9]] = True
    out = tmp_path / "traj.png"
    fig = draw_trajectory(
        corridor,
        poses,
        footprints_every=5,
        sonar_at=[10],
        ranges=ranges,
        stalled=stalled,
        label="robot",
        path=out,
    )
    ax = fig.axes[0]
    (line,) = [ln for ln in ax.get_lines() if ln.get_gid() == "path"]
    np.testing.assert_allclose(np.asarray(line.get_xydata()), poses[:, :2])
    feet = [p for p in ax.patches if p.get_gid() == "footprint"]
    assert len(feet) == 5  # samples 0, 5, 10, 15, 20
    np.testing.assert_allclose(feet[0].get_xy()[:8], np.asarray(body_polygon(poses[0])))
    np.testing.assert_allclose(feet[-1].get_xy()[:8], np.asarray(body_polygon(poses[-1])))
    (stalls,) = [ln for ln in ax.get_lines() if ln.get_gid() == "stalls"]
    np.testing.assert_allclose(np.asarray(stalls.get_xydata()), poses[[4, 9], :2])
    rays = [c for c in ax.collections if c.get_gid() == "rays"]
    segs = [s for c in rays for s in c.get_segments()]
    assert len(segs) == 16
    origins, angles = sonar_rays(poses[10])
    origins, angles = np.asarray(origins), np.asarray(angles)
    starts = np.array([s[0] for s in segs])
    lengths = np.array([np.hypot(*(s[1] - s[0])) for s in segs])
    for k in range(16):  # every sonar's ray starts at its origin, as long as its reading
        j = int(np.argmin(np.hypot(*(starts - origins[k]).T)))
        assert np.hypot(*(starts[j] - origins[k])) < 1e-9
        assert lengths[j] == pytest.approx(ranges[10, k])
    assert out.stat().st_size > 10_000


def test_draw_trajectory_on_given_axes_and_paper_sonars(corridor):
    fig = draw_maze(corridor)
    ax = fig.axes[0]
    poses = np.array([[2.0, 1.8, 0.0], [2.5, 1.8, 0.0]])
    ranges = np.full((2, 10), 0.4)  # the paper's 10 sonars by default
    got = draw_trajectory(corridor, poses, ax, sonar_at=[-1], ranges=ranges, color="black")
    assert got is fig
    segs = [s for c in ax.collections if c.get_gid() == "rays" for s in c.get_segments()]
    assert len(segs) == 10
    with pytest.raises(MbnInputError, match="sonars"):
        draw_trajectory(corridor, poses, sonar_at=[0], ranges=np.ones((2, 7)))
    with pytest.raises(MbnInputError, match=r"\(n, 3\)"):
        draw_trajectory(corridor, np.zeros((4, 2)))


def constant_controller(state, obs):
    """Drive at 0.4 m/s, turning at the robot's own constant rate (its state)."""
    return state, (jnp.asarray(0.4), state)


def test_plot_episodes_small_multiples_and_overlay(corridor, tee, tmp_path):
    world = compile_mazes([corridor])
    cfg = RolloutConfig(steps=30, record_every=2, sensors=SensorConfig(sonars=ALL_SONARS))
    starts = jnp.array([[2.0, 1.8, 0.0], [2.0, 1.8, 0.1], [3.0, 1.8, -0.1]])
    run = jax.jit(lambda s, p: rollout(world, constant_controller, s, p, jnp.zeros(3, int), cfg))
    traj = run(jnp.array([0.0, 0.2, -0.3]), starts).trajectory
    assert isinstance(traj, Trajectory)
    out = tmp_path / "episodes.png"
    fig = plot_episodes(corridor, traj, [0, 2], path=out)
    shown = [ax for ax in fig.axes if ax.get_visible()]
    assert len(shown) == 2
    for ax, i in zip(shown, [0, 2], strict=True):
        (line,) = [ln for ln in ax.get_lines() if ln.get_gid() == "path"]
        np.testing.assert_allclose(np.asarray(line.get_xydata()), np.asarray(traj.pose[i, :, :2]))
        assert ax.get_title().startswith(f"robot {i}:")
    assert out.stat().st_size > 10_000
    fig = plot_episodes(corridor, traj, [0, 1, 2], overlay=True, titles=["a", "b", "c"])
    (ax,) = fig.axes
    paths = [ln for ln in ax.get_lines() if ln.get_gid() == "path"]
    assert [ln.get_label() for ln in paths] == ["a", "b", "c"]
    assert len({ln.get_color() for ln in paths}) == 3
    with pytest.raises(MbnInputError, match="out of range"):
        plot_episodes(corridor, traj, [3])


def test_episode_view_frames_move_with_the_robot(tee):
    view = EpisodeView(tee, camera_fov_deg=60.0)
    view.update([3.0, 1.8, math.pi / 2], ranges=np.full(16, 1.0), camera=1, tile=0, t=0.0)
    a = view.rgb()
    assert a.dtype == np.uint8 and a.ndim == 3 and a.shape[2] == 3
    view.update([3.0, 3.0, math.pi / 2], ranges=np.full(16, 1.0), camera=1, tile=0, t=0.0)
    b = view.rgb()
    assert a.shape == b.shape and np.any(a != b)
    # the status line stays in the frame
    box = view.ax.title.get_window_extent()
    assert box.y0 >= 0 and box.y1 <= a.shape[0] and "camera: 1-colour" in view.ax.get_title()
    # the sonar rays start at the sonars' origins
    segs = view.rays.get_segments()
    origins = np.asarray(sonar_rays(np.array([3.0, 3.0, math.pi / 2]), SONAR_POSES)[0])
    np.testing.assert_allclose(np.array([s[0] for s in segs]), origins, atol=1e-6)
