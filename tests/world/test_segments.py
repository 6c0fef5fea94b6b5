"""The segment path of the engine (worlds that are not grids: walls on a fine step or none, far
apart, huge extents) agrees with the exact geometry of :mod:`mbn.world.geometry`, stays small,
and runs the robot step (sonars, camera, tile under the body, collision) like the lattice."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.world import engine as E  # noqa: N812
from mbn.world.geometry import collides, rect_segments, sonar_ranges, sonar_rays
from mbn.world.mazes.builtin import crossroad, stage_arena
from mbn.world.mazes.model import Maze, Tile
from mbn.world.rollout import RolloutConfig, junction_arrays, rollout

#: Sonar agreement with the exact caster (metres); the tests run in float64, where the segment
#: path evaluates the caster's own formula and agrees to about 1e-14.
TOL = 2e-5


def _fine_maze(step: float, seed: int) -> Maze:
    """A walled 6 x 3.4 m room with rectangles whose edges lie on multiples of ``step``."""
    rng = np.random.default_rng(seed)
    walls = []
    for _ in range(6):
        x0, y0 = rng.uniform(0.5, 5.0), rng.uniform(0.3, 2.8)
        w, h = rng.uniform(0.05, 0.8), rng.uniform(0.05, 0.8)
        walls.append([x0, x0 + w, y0, y0 + h])
    walls = np.round(np.array(walls) / step) * step
    return Maze(f"fine{step}", walls=walls, bounds=(0.0, 6.01, 0.0, 3.37), outside_is_wall=True)


def _odd_open_maze(seed: int) -> Maze:
    """An open world of rectangles at arbitrary coordinates (no common step)."""
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-7.0, 7.0, (25, 2))
    size = rng.uniform(0.05, 1.5, (25, 2))
    walls = np.stack([lo[:, 0], lo[:, 0] + size[:, 0], lo[:, 1], lo[:, 1] + size[:, 1]], -1)
    x0, y0 = walls[:, 0].min(), walls[:, 2].min()
    x1, y1 = walls[:, 1].max(), walls[:, 3].max()
    return Maze("odd", walls=walls, bounds=(x0, x1, y0, y1), outside_is_wall=False)


def _two_walls(apart: float = 2000.0) -> Maze:
    walls = [[0.0, 1.0, 0.0, 1.0], [apart, apart + 1.0, apart, apart + 1.0]]
    return Maze(
        "far", walls=walls, bounds=(0.0, apart + 1.0, 0.0, apart + 1.0), outside_is_wall=False
    )


NON_GRID = {
    "fine_0.05": _fine_maze(0.05, 0),
    "fine_0.01": _fine_maze(0.01, 1),
    "odd_open": _odd_open_maze(2),
    "two_walls_2km": _two_walls(),
}


def _poses(maze: Maze, n: int, seed: int) -> np.ndarray:
    """Random poses around the walls (near a random wall for open worlds)."""
    rng = np.random.default_rng(seed)
    if maze.outside_is_wall:
        x0, x1, y0, y1 = maze.bounds
        xy = np.stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)], -1)
    else:
        w = maze.walls[rng.integers(len(maze.walls), size=n)]
        xy = np.stack(
            [rng.uniform(w[:, 0] - 3, w[:, 1] + 3), rng.uniform(w[:, 2] - 3, w[:, 3] + 3)], -1
        )
    return np.concatenate([xy, rng.uniform(-math.pi, math.pi, (n, 1))], -1)


@jax.jit
def _sense(world: E.World, p: jax.Array) -> tuple[jax.Array, jax.Array]:
    mi = jnp.zeros(p.shape[0], jnp.int32)
    mc = E.maze_constants(world, mi)
    words, ci, cj = E.window_words(world, mc, p[:, 0], p[:, 1])
    o, a = sonar_rays(p)
    ranges = E.cast(world, mc, words, ci, cj, o[..., 0], o[..., 1], a)
    return ranges, E.collides_cells(world, mc, words, ci, cj, p)


def _sonars_free(maze: Maze, poses: np.ndarray) -> np.ndarray:
    origins = np.asarray(sonar_rays(poses)[0])
    return np.array([all(maze.is_free(float(x), float(y)) for x, y in o) for o in origins])


@pytest.mark.parametrize(
    "name", [pytest.param(n, marks=pytest.mark.slow) if n != "fine_0.01" else n for n in NON_GRID]
)
def test_segment_path_equals_the_exact_caster_and_collision(name):
    maze = NON_GRID[name]
    assert not E.uses_lattice([maze])
    world = E.compile_mazes([maze])
    assert world.mode == "segments"
    poses = _poses(maze, 3000, seed=7)
    ranges, hit = (np.asarray(a) for a in _sense(world, jnp.asarray(poses)))
    exact_hit = np.asarray(collides(jnp.asarray(poses), maze.solid_rects()))
    assert 0 < exact_hit.sum() < len(poses)  # both outcomes occur
    np.testing.assert_array_equal(hit, exact_hit)
    ok = ~exact_hit & _sonars_free(maze, poses)
    exact = np.asarray(sonar_ranges(poses, rect_segments(maze.solid_rects())))
    assert ok.sum() > 500
    assert (exact[ok] < 5.0).sum() > 2000  # many rays meet walls
    np.testing.assert_allclose(ranges[ok], exact[ok], rtol=0, atol=TOL)


def test_far_apart_walls_compile_small():
    for apart in (2000.0, 200_000.0):
        world = E.compile_mazes([_two_walls(apart)])
        total = sum(int(np.asarray(leaf).nbytes) for leaf in jax.tree.leaves(world))
        assert world.mode == "segments"
        assert total < 2 * 2**20, total
        assert world.n_seg <= 8 and world.n_rect <= 2


def test_lattice_is_kept_for_grids_and_coarse_steps():
    assert E.uses_lattice([crossroad("LSR"), crossroad("R")])
    assert E.uses_lattice([stage_arena()])  # 0.2 m lattice
    assert E.compile_mazes([crossroad("LSR")]).mode == "lattice"
    # a grid maze mixed with a world that is not a grid: both on the segment path
    assert not E.uses_lattice([crossroad("LSR"), NON_GRID["fine_0.01"]])


def _tiled_maze() -> Maze:
    """A corridor on a 0.4 m lattice with tiles."""
    tiles = (
        Tile(x=3.0, y=0.6, colors=2, heading=0.0, width=1.2, length=0.3),
        Tile(x=4.5, y=0.6, colors=1, heading=0.0, width=1.2, length=0.3),
    )
    return Maze(
        "tiled",
        walls=[[2.0, 2.4, 0.0, 0.4]],
        bounds=(0.0, 6.0, 0.0, 1.2),
        tiles=tiles,
        outside_is_wall=True,
    )


def _episode(world: E.World, mazes: list[Maze], start: np.ndarray, camera: E.CameraConfig | None):
    def drive(state, obs):
        v = jnp.where(obs.ranges[3] < 0.6, 0.1, 0.4)
        return state, (v, jnp.asarray(0.25) * jnp.sin(state.sum() + obs.t))

    config = RolloutConfig(steps=150, camera=camera, record_every=1)
    junctions = junction_arrays(mazes, world)
    n = len(start)
    return rollout(
        world,
        drive,
        jnp.zeros((n, 1)),
        jnp.asarray(start),
        jnp.zeros(n, jnp.int32),
        config,
        junctions=junctions,
    )


@pytest.mark.slow  # 25 s; the cheaper equivalence tests above stay in CI
def test_rollout_on_the_segment_path_equals_the_lattice(monkeypatch):
    maze = _tiled_maze()
    lat = E.compile_mazes([maze])
    monkeypatch.setattr(E, "LATTICE_MAX_WORDS", 1)  # the same maze on the segment path
    seg = E.compile_mazes([maze])
    assert (seg.mode, lat.mode) == ("segments", "lattice")
    start = np.array([[0.6, 0.6, 0.0], [5.4, 0.6, math.pi], [1.0, 0.9, -0.3]])
    cam = E.CameraConfig()
    a = _episode(seg, [maze], start, cam).trajectory
    b = _episode(lat, [maze], start, cam).trajectory
    np.testing.assert_allclose(np.asarray(a.pose), np.asarray(b.pose), atol=1e-9)
    np.testing.assert_allclose(np.asarray(a.ranges), np.asarray(b.ranges), atol=TOL)
    for field in ("camera", "blobs", "tile", "stalled"):
        np.testing.assert_array_equal(np.asarray(getattr(a, field)), np.asarray(getattr(b, field)))
    assert np.asarray(a.stalled).any() and np.asarray(a.tile).max() == 2
    assert np.asarray(a.camera).max() > 0


@pytest.mark.slow
def test_grid_maze_on_the_segment_path_keeps_its_junctions():
    mazes = [crossroad("LSR"), NON_GRID["fine_0.01"]]
    world = E.compile_mazes(mazes)
    assert world.mode == "segments"
    alone = E.compile_mazes(mazes[:1])
    start = np.asarray(mazes[0].starts[:1])
    a = _episode(world, mazes, start, None)
    b = _episode(alone, mazes[:1], start, None)
    np.testing.assert_allclose(
        np.asarray(a.trajectory.pose), np.asarray(b.trajectory.pose), atol=1e-9
    )
    np.testing.assert_array_equal(
        np.asarray(a.stats.junction_exit), np.asarray(b.stats.junction_exit)
    )
