"""The compiled engine (lattice ray marching with culled windows, cell collision, camera) agrees
with the exact segment geometry of :mod:`mbn.world.geometry` on every kind of maze."""

from __future__ import annotations

import math
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbn.errors import MbnInputError
from mbn.world import engine as E  # noqa: N812
from mbn.world.geometry import cast_rays, collides, rect_segments, sonar_ranges, sonar_rays
from mbn.world.mazes.builtin import crossroad, stage_arena
from mbn.world.mazes.generate import corridor_maze
from mbn.world.mazes.model import Maze, Tile, merge_cells


def _mazes() -> dict[str, Maze]:
    open_maze = Maze(
        "open",
        walls=[[0.0, 0.5, 0.0, 3.0], [2.0, 2.25, 1.0, 1.5], [1.0, 4.0, 2.5, 2.75]],
        bounds=(0.0, 4.0, 0.0, 3.0),
        outside_is_wall=False,
    )
    return {
        "cross_LSR": crossroad("LSR"),
        "cross_R": crossroad("R"),
        "arena": stage_arena(),
        "large": corridor_maze(30, 30, seed=3, loops=0.2),
        "open": open_maze,
    }


MAZES = _mazes()


def _random_poses(maze: Maze, n: int, seed: int) -> np.ndarray:
    x0, x1, y0, y1 = maze.bounds
    rng = np.random.default_rng(seed)
    pad = 0.0 if maze.outside_is_wall else 2.0
    return np.stack(
        [
            rng.uniform(x0 - pad, x1 + pad, n),
            rng.uniform(y0 - pad, y1 + pad, n),
            rng.uniform(-math.pi, math.pi, n),
        ],
        -1,
    )


@jax.jit
def _ranges(world: E.World, maze_index: jax.Array, p: jax.Array) -> jax.Array:
    mc = E.maze_constants(world, maze_index)
    words, ci, cj = E.window_words(world, mc, p[:, 0], p[:, 1])
    origins, angles = sonar_rays(p)
    return E.cast(world, mc, words, ci, cj, origins[..., 0], origins[..., 1], angles)


@jax.jit
def _collides(world: E.World, maze_index: jax.Array, p: jax.Array) -> jax.Array:
    mc = E.maze_constants(world, maze_index)
    words, ci, cj = E.window_words(world, mc, p[:, 0], p[:, 1])
    return E.collides_cells(world, mc, words, ci, cj, p)


@partial(jax.jit, static_argnums=3)
def _camera(world: E.World, maze_index: jax.Array, p: jax.Array, cfg: E.CameraConfig):
    mc = E.maze_constants(world, maze_index)
    words, ci, cj = E.window_words(world, mc, p[:, 0], p[:, 1])
    return E.see_tiles(world, mc, maze_index, words, ci, cj, p, cfg)


def _engine_ranges(world: E.World, m: int, poses: np.ndarray) -> np.ndarray:
    p = jnp.asarray(poses)
    return np.asarray(_ranges(world, jnp.full(len(poses), m, jnp.int32), p))


WORLDS: dict[str, E.World] = {}


def _world(name: str) -> E.World:
    """Each maze compiled alone (a fine lattice like the arena's would slow every other one)."""
    if name not in WORLDS:
        WORLDS[name] = E.compile_mazes([MAZES[name]])
    return WORLDS[name]


_exact_ranges = jax.jit(sonar_ranges)
_exact_collides = jax.jit(collides)


@pytest.mark.parametrize(
    "m,name",
    [
        (m, n) if n != "open" else pytest.param(m, n, marks=pytest.mark.slow)
        for m, n in enumerate(MAZES)
    ],
)
def test_lattice_rays_equal_exact_segment_rays(m, name):
    maze = MAZES[name]
    poses = _random_poses(maze, 1500, seed=m)
    free = ~np.asarray(_exact_collides(jnp.asarray(poses), maze.solid_rects()))
    poses = poses[free]
    assert len(poses) > 100
    ours = _engine_ranges(_world(name), 0, poses)
    exact = np.asarray(_exact_ranges(jnp.asarray(poses), rect_segments(maze.solid_rects())))
    assert ours.shape == exact.shape == (len(poses), 16)
    np.testing.assert_allclose(ours, exact, atol=2e-5)
    assert ours.min() >= 0.0 and ours.max() <= 5.0


@pytest.mark.parametrize("m,name", list(enumerate(MAZES)))
def test_cell_collision_equals_exact_polygon_test(m, name):
    maze = MAZES[name]
    poses = jnp.asarray(_random_poses(maze, 5000, seed=100 + m))
    ours = np.asarray(_collides(_world(name), jnp.zeros(len(poses), jnp.int32), poses))
    exact = np.asarray(_exact_collides(poses, maze.solid_rects()))
    assert 0 < exact.sum() < len(exact)  # both outcomes occur
    np.testing.assert_array_equal(ours, exact)


def test_lattices_are_exact_and_culling_is_size_independent():
    assert E.lattice_cell(MAZES["cross_LSR"]) == (1.2, (0.0, 0.0))
    assert E.lattice_cell(MAZES["arena"])[0] == pytest.approx(0.2)
    assert E.lattice_cell(MAZES["open"])[0] == pytest.approx(0.25)
    # a crossroad and a 30 x 30 maze compile to the same window and march length
    small = E.compile_mazes([MAZES["cross_LSR"]])
    large = E.compile_mazes([MAZES["large"]])
    assert (small.n_words, small.n_march, small.n_body) == (large.n_words, large.n_march, 2)
    assert large.n_words == 4 and large.n_march == 12


def test_incommensurable_walls_are_refused():
    odd = Maze(
        "odd",
        walls=[[0.0, 1.0, 0.0, 1.0], [1.0, 1.0 + math.pi / 100, 0.0, 1.0]],
        bounds=(0.0, 2.0, 0.0, 1.0),
    )
    with pytest.raises(MbnInputError, match="common step"):
        E.lattice_cell(odd)


def _free_centres(maze: Maze) -> list[tuple[float, float]]:
    rows = maze.grid.shape[0]
    return [((c + 0.5) * 1.2, (rows - r - 0.5) * 1.2) for r, c in np.argwhere(maze.grid != "#")]


#: Offsets within a cell that keep the body (radius 0.315 m) clear of a 1.2 m corridor's walls.
_OFFSET = st.floats(-0.25, 0.25)


@settings(max_examples=40, deadline=None)
@given(
    centre=st.sampled_from(_free_centres(crossroad("LS"))),
    dx=_OFFSET,
    dy=_OFFSET,
    th=st.floats(-math.pi, math.pi),
    shift=st.tuples(st.integers(-3, 3), st.integers(-3, 3)),
)
def test_readings_invariant_under_lattice_translation(centre, dx, dy, th, shift):
    """Translating maze and robot together by whole cells leaves every reading unchanged."""
    base = crossroad("LS")
    tx, ty = shift[0] * 1.2, shift[1] * 1.2
    moved = Maze(
        "moved",
        walls=base.walls + np.array([tx, tx, ty, ty]),
        bounds=(tx, tx + 8.4, ty, ty + 8.4),
    )
    w = E.compile_mazes([base, moved])
    pose = np.array([[centre[0] + dx, centre[1] + dy, th]])
    a = _engine_ranges(w, 0, pose)
    b = _engine_ranges(w, 1, pose + np.array([[tx, ty, 0.0]]))
    np.testing.assert_allclose(a, b, atol=5e-5)
    assert a.min() >= 0.0 and a.max() <= 5.0


def test_camera_sees_tiles_in_view_and_not_behind_walls():
    maze = Maze(
        "tiles",
        walls=crossroad("LSR").walls,
        bounds=(0.0, 8.4, 0.0, 8.4),
        tiles=(
            Tile(4.2, 2.2, 2),  # in the south arm, ahead of a robot at (4.2, 0.6) facing north
            Tile(1.2, 4.2, 1, heading=0.0),  # in the west arm: hidden from the south arm
        ),
    )
    w = E.compile_mazes([maze])
    poses = jnp.asarray(
        [
            [4.2, 0.6, math.pi / 2],  # facing the two-colour tile 1.6 m ahead
            [4.2, 0.6, -math.pi / 2],  # facing away
            [4.2, 4.2, math.pi],  # in the junction facing west: one-colour tile 3 m away
            [4.2, 1.5, 0.0],  # tile at 90 degrees: out of the 60-degree view
        ]
    )
    mi = jnp.zeros(4, jnp.int32)
    cam = _camera(w, mi, poses, E.CameraConfig(range=3.5))
    assert np.asarray(cam.nearest).tolist() == [2, 0, 1, 0]
    assert np.asarray(cam.blobs).tolist() == [2, 0, 1, 0]
    # the two blobs of the two-colour tile lie left and right of the heading
    b0, b1, _ = np.asarray(cam.bearing)[0, 0]
    assert b0 * b1 < 0 and not np.asarray(cam.visible)[0, 0, 2]
    # a wall between camera and tile hides it: west tile seen from the south arm
    hidden = jnp.asarray([[4.2, 2.0, math.radians(135.0)]])
    cam1 = _camera(w, jnp.zeros(1, jnp.int32), hidden, E.CameraConfig(range=5))
    assert bool(np.asarray(cam1.visible)[0, 1, 0]) is False
    # driving over: the tile under the middle of the body
    under = E.tile_under(w, mi, jnp.asarray([[4.25, 2.2, math.pi / 2]] * 4))
    assert np.asarray(under).tolist() == [2, 2, 2, 2]


def test_a_three_colour_tile_shows_three_blobs_left_middle_and_right():
    maze = Maze(
        name="three",
        walls=crossroad("LSR").walls,
        bounds=(0.0, 8.4, 0.0, 8.4),
        tiles=(Tile(4.2, 2.2, 3),),
    )
    w = E.compile_mazes([maze])
    poses = jnp.asarray([[4.2, 0.6, math.pi / 2], [4.2, 0.6, -math.pi / 2]])
    cam = _camera(w, jnp.zeros(2, jnp.int32), poses, E.CameraConfig(range=3.5))
    assert np.asarray(cam.nearest).tolist() == [3, 0]
    assert np.asarray(cam.blobs).tolist() == [3, 0]
    assert np.asarray(cam.visible)[0, 0].tolist() == [True, True, True]
    # the thirds side by side across the corridor: one on each side of the heading, one ahead
    b0, b1, b2 = np.asarray(cam.bearing)[0, 0]
    assert b0 * b2 < 0 and abs(b1) < min(abs(b0), abs(b2))
    under = E.tile_under(w, jnp.zeros(1, jnp.int32), jnp.asarray([[4.25, 2.2, math.pi / 2]]))
    assert np.asarray(under).tolist() == [3]
    with pytest.raises(MbnInputError, match="tile colors must be an integer from 1 to 6, got 7"):
        Tile(1.0, 1.0, 7)


def test_camera_config_is_validated():
    with pytest.raises(MbnInputError, match="fov"):
        E.CameraConfig(fov_deg=0.0)
    with pytest.raises(MbnInputError, match="range"):
        E.CameraConfig(range=12.0)


def test_compile_needs_a_maze():
    with pytest.raises(MbnInputError, match="at least one"):
        E.compile_mazes([])


def test_batch_composition_does_not_change_readings():
    mazes = [MAZES["large"], MAZES["cross_R"]]
    world = E.compile_mazes(mazes)
    poses = _random_poses(mazes[0], 200, seed=7)
    poses = poses[~np.asarray(_exact_collides(jnp.asarray(poses), mazes[0].solid_rects()))]
    alone = _engine_ranges(world, 0, poses[:5])
    together = _engine_ranges(world, 0, poses)
    np.testing.assert_array_equal(alone, together[:5])


_TURN_BASE = corridor_maze(7, 7, seed=5, loops=0.5)


@settings(max_examples=30, deadline=None)
@given(
    centre=st.sampled_from(_free_centres(_TURN_BASE)),
    dx=_OFFSET,
    dy=_OFFSET,
    th=st.floats(-math.pi, math.pi),
    turns=st.integers(1, 3),
)
def test_readings_invariant_under_quarter_turns_of_maze_and_robot(centre, dx, dy, th, turns):
    """Rotating a grid maze and the robot together by 90-degree turns changes no reading."""
    base = _TURN_BASE
    grid = np.rot90(base.grid, turns)  # counter-clockwise, like the pose rotation below
    side = 7 * 1.2
    turned = Maze(
        "turned",
        walls=merge_cells(grid == "#", 1.2),
        bounds=(0.0, side, 0.0, side),
        grid=grid,
        cell=1.2,
    )
    pose = np.array([centre[0] + dx, centre[1] + dy, th])
    c = np.array([side / 2, side / 2])
    a = turns * math.pi / 2
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    moved = np.concatenate([rot @ (pose[:2] - c) + c, [th + a]])
    r0 = _engine_ranges(E.compile_mazes([base]), 0, pose[None])
    r1 = _engine_ranges(E.compile_mazes([turned]), 0, moved[None])
    np.testing.assert_allclose(r0, r1, atol=5e-5)


def _reference_camera(maze: Maze, poses: np.ndarray, cfg: E.CameraConfig):
    """The blob finder by exact geometry, in float64 and with angles, from each of ``poses``
    ``(P, 3)``: which sample points of each tile the camera sees ``(P, tiles, 4)``, and how far
    the sample points of a pose are from the edges of the tests ``(P,)`` (field of view, range,
    occlusion)."""
    segments = rect_segments(maze.walls)
    x, y, th = (poses[:, i, None, None] for i in range(3))
    cx, cy = x + np.cos(th) * E.CAMERA_POSITION[0], y + np.sin(th) * E.CAMERA_POSITION[0]
    h = np.array([[t.heading] for t in maze.tiles])
    width = np.array([[t.width] for t in maze.tiles])
    px = np.array([[t.x] for t in maze.tiles]) - E._TILE_SAMPLES * width * np.sin(h)
    py = np.array([[t.y] for t in maze.tiles]) + E._TILE_SAMPLES * width * np.cos(h)
    dist = np.hypot(px - cx, py - cy)  # (P, tiles, 4)
    ang = np.arctan2(py - cy, px - cx)
    rel = np.angle(np.exp(1j * (ang - th)))
    origins = np.stack(np.broadcast_arrays(cx, cy), -1)
    free = np.asarray(cast_rays(origins, ang, segments, cfg.range))
    half = math.radians(cfg.fov_deg) / 2
    seen = (np.abs(rel) <= half) & (dist <= cfg.range) & (free >= dist - 1e-4)
    edges = np.minimum(
        np.abs(np.abs(rel) - half), np.minimum(np.abs(dist - cfg.range), np.abs(free - dist))
    )
    return seen, edges.min(axis=(1, 2))


@pytest.mark.parametrize(
    "view_range",
    [0.8, 3.0],  # 0.8 m: the default camera
)
def test_camera_agrees_with_exact_geometry_in_the_test_mazes(view_range):
    """The engine's blob finder (field of view by the cosine of the angle off the axis, rays
    marched only as far as the camera reads) sees what exact geometry with angles sees, from
    random free poses in fig4 and the held-out maze, wherever no sample point lies within 1e-3
    (rad or m) of an edge of the tests."""
    from mbn.world.mazes.builtin import builtin_maze

    cfg = E.CameraConfig(range=view_range)
    checked = seeing = 0
    for name in ("fig4", "heldout"):
        maze = builtin_maze(name)
        w = E.compile_mazes([maze])
        rng = np.random.default_rng(7)
        x0, x1, y0, y1 = maze.bounds
        # poses near tiles, so that most of them see one
        centres = np.array([(t.x, t.y) for t in maze.tiles])
        near = centres[rng.integers(0, len(centres), 1000)] + rng.uniform(-1.2, 1.2, (1000, 2))
        poses = np.column_stack([near, rng.uniform(-math.pi, math.pi, 1000)])
        inside = (poses[:, 0] > x0) & (poses[:, 0] < x1) & (poses[:, 1] > y0) & (poses[:, 1] < y1)
        poses = poses[inside]
        poses = poses[~np.asarray(collides(poses, maze.walls))]
        cam = _camera(w, jnp.zeros(len(poses), jnp.int32), jnp.asarray(poses, jnp.float32), cfg)
        blobs, nearest = np.asarray(cam.blobs), np.asarray(cam.nearest)
        seen_all, margins = _reference_camera(maze, poses, cfg)
        for i, pose in enumerate(poses):
            seen, margin = seen_all[i], margins[i]
            if margin < 1e-3:
                continue
            checked += 1
            colors = np.array([t.colors for t in maze.tiles])
            vis0 = np.array(
                [s[:2].any() if c == 2 else s.any() for s, c in zip(seen, colors, strict=True)]
            )
            vis1 = np.array(
                [s[2:].any() if c == 2 else False for s, c in zip(seen, colors, strict=True)]
            )
            assert int(blobs[i]) == int(vis0.sum() + vis1.sum()), (name, pose)
            any_vis = vis0 | vis1
            d = np.hypot(
                centres[:, 0] - pose[0] - math.cos(pose[2]) * E.CAMERA_POSITION[0],
                centres[:, 1] - pose[1] - math.sin(pose[2]) * E.CAMERA_POSITION[0],
            )
            want = int(colors[np.argmin(np.where(any_vis, d, np.inf))]) if any_vis.any() else 0
            assert int(nearest[i]) == want, (name, pose)
            seeing += want > 0
    assert checked > 300 and seeing > 50, (checked, seeing)
