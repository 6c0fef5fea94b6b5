"""Pictures of mazes and episodes: the figures hold the right geometry and the files are real."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from matplotlib.figure import Figure
from PIL import Image

from mbn.errors import MbnInputError
from mbn.viz.render import (
    EpisodeView,
    animate_episode,
    draw_maze,
    draw_trajectory,
    plot_episodes,
    save_maze_png,
)
from mbn.world.engine import compile_mazes
from mbn.world.geometry import body_polygon, sonar_rays
from mbn.world.mazes.model import Maze, Tile, merge_cells
from mbn.world.robot import SONAR_POSES
from mbn.world.rollout import RolloutConfig, Trajectory, rollout
from mbn.world.sensors import ALL_SONARS, SensorConfig

CELL = 1.2


def grid_maze(rows: list[str], name: str, **kw: object) -> Maze:
    grid = np.array([list(r) for r in rows])
    r, c = grid.shape
    return Maze(
        name=name,
        walls=merge_cells(grid == "#", CELL),
        bounds=(0.0, c * CELL, 0.0, r * CELL),
        grid=grid,
        cell=CELL,
        **kw,  # type: ignore[arg-type]
    )


@pytest.fixture(scope="module")
def tee() -> Maze:
    """A T junction: a corridor west-east on row 1, a stem going south from its middle."""
    return grid_maze(
        ["#####", "#...#", "##.##", "##.##", "#####"],
        "tee",
        tiles=(Tile(3.0, 2.4, 1, heading=math.pi / 2), Tile(1.8, 4.2, 2, heading=0.0)),
        starts=[[3.0, 1.8, math.pi / 2], [1.8, 4.2, 0.0]],
    )


@pytest.fixture(scope="module")
def corridor() -> Maze:
    """A corridor 1.2 m wide along x, from x = 1.2 to 7.2."""
    return grid_maze(["#######", "#.....#", "#######"], "corridor", starts=[[2.0, 1.8, 0.0]])


def patches(ax, gid: str) -> list:
    return [p for p in ax.patches if p.get_gid() == gid]


def test_draw_maze_draws_walls_tiles_decision_cells_and_starts(tee):
    fig = draw_maze(tee)
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    walls = patches(ax, "wall")
    got = sorted(
        (p.get_x(), p.get_x() + p.get_width(), p.get_y(), p.get_y() + p.get_height()) for p in walls
    )
    np.testing.assert_allclose(np.array(got), np.array(sorted(map(tuple, tee.walls))))
    # the T's junction (row 1, column 2) is the only decision cell
    (dec,) = patches(ax, "decision")
    assert (dec.get_x(), dec.get_y(), dec.get_width()) == pytest.approx((2.4, 3.6, CELL))
    (one,) = patches(ax, "tile1")
    np.testing.assert_allclose(one.get_xy()[:4], tee.tiles[0].corners())
    halves = patches(ax, "tile2")
    assert len(halves) == 2
    assert {tuple(p.get_facecolor()) for p in halves} != {tuple(halves[0].get_facecolor())}
    union = np.concatenate([h.get_xy()[:4] for h in halves])
    corners = tee.tiles[1].corners()
    assert union[:, 0].min() == pytest.approx(corners[:, 0].min())
    assert union[:, 1].max() == pytest.approx(corners[:, 1].max())
    assert len(patches(ax, "start")) == 2
    assert len(patches(ax, "frame")) == 4  # outside is wall
    assert ax.get_aspect() == 1.0
    assert ax.get_title() == "tee"


def test_open_maze_has_no_frame_and_no_decision_cells():
    maze = Maze(
        name="open",
        walls=[[0.0, 1.0, 0.0, 3.0], [2.2, 3.2, 0.0, 3.0]],
        bounds=(0.0, 3.2, 0.0, 3.0),
        outside_is_wall=False,
    )
    ax = draw_maze(maze, junctions=True, title="").axes[0]
    assert patches(ax, "frame") == [] and patches(ax, "decision") == []
    assert len(patches(ax, "wall")) == 2
    assert ax.get_title() == ""


def test_save_maze_png_writes_a_real_png(tee, tmp_path):
    out = tmp_path / "tee.png"
    fig = save_maze_png(tee, out, title="a T junction")
    assert isinstance(fig, Figure)
    assert out.stat().st_size > 10_000
    with Image.open(out) as im:
        assert im.format == "PNG"
        assert im.width > 500 and im.height > 500
        pixels = np.asarray(im.convert("RGB"))
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 10  # not a blank picture
    assert not list(tmp_path.glob(".*"))  # no temporary file left behind
    with pytest.raises(MbnInputError, match="does not exist"):
        save_maze_png(tee, tmp_path / "missing" / "x.png")


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
    feet = patches(ax, "footprint")
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


def test_animate_episode_writes_a_gif_with_the_expected_frames(tee, tmp_path):
    n = 30
    poses = np.stack(
        [np.full(n, 3.0), np.linspace(1.8, 4.0, n), np.linspace(math.pi / 2, 2.0, n)], -1
    )
    ranges = np.tile(np.linspace(0.3, 5.0, 16), (n, 1))
    camera = (np.arange(n) // 10) % 3
    tile = np.where(np.arange(n) > 15, 1, 0)
    out = tmp_path / "episode.gif"
    fig = animate_episode(
        tee, poses, out, ranges=ranges, camera=camera, tile=tile, stalled=np.arange(n) == 5
    )
    assert isinstance(fig, Figure)
    assert out.stat().st_size > 20_000
    with Image.open(out) as im:
        assert im.format == "GIF"
        assert im.n_frames == n
        assert im.info["duration"] == 100
    # subsampled to at most max_frames: every = ceil(31 / 10) = 4, so ceil(31 / 4) = 8 frames
    poses31 = np.concatenate([poses, poses[-1:]])
    animate_episode(tee, poses31, out, max_frames=10, fps=5)
    with Image.open(out) as im:
        assert im.n_frames == 8
        assert im.info["duration"] == 200
    animate_episode(tee, poses, out, every=7)
    with Image.open(out) as im:
        assert im.n_frames == 5
    assert not list(tmp_path.glob(".*"))
    with pytest.raises(MbnInputError, match="every"):
        animate_episode(tee, poses, out, every=0)
    with pytest.raises(MbnInputError, match="samples"):
        animate_episode(tee, poses, out, camera=np.zeros(n + 1))


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
