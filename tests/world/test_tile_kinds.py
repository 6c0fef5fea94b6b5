"""Tiles of one to six colours: the camera shows a blob per colour (a world with tiles of at most
three colours reads as it always did), the readers take them, the families tiles4, tiles5 and
tiles6 place them, and a tile of seven colours is refused in one line."""

from __future__ import annotations

import math
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.world import engine as E  # noqa: N812
from mbn.world.junctions import rule_route
from mbn.world.mazes import families as fm
from mbn.world.mazes.builtin import crossroad
from mbn.world.mazes.grid_text import parse_maze_text
from mbn.world.mazes.model import TILE_COLORS, Maze, Tile
from mbn.world.mazes.toml_maze import parse_toml_maze
from mbn.world.senses import Senses, camera_noise
from mbn.world.sensors import NoiseConfig
from mbn.world.step import locate, sense

#: The crossroad's walls (cells of 1.2 m, the junction at (4.2, 4.2)); a tile across the south
#: arm at y = 2.2 is 1.6 m ahead of a robot at (4.2, 0.6) facing north.
WALLS = crossroad("LSR").walls
BOUNDS = (0.0, 8.4, 0.0, 8.4)
FACING = (4.2, 0.6, math.pi / 2)
VIEW = E.CameraConfig(range=3.5)


@partial(jax.jit, static_argnums=3)
def _camera(world: E.World, maze_index: jax.Array, p: jax.Array, cfg: E.CameraConfig):
    mc = E.maze_constants(world, maze_index)
    words, ci, cj = E.window_words(world, mc, p[:, 0], p[:, 1])
    return E.see_tiles(world, mc, maze_index, words, ci, cj, p, cfg)


def _maze(*tiles: Tile) -> Maze:
    return Maze("kinds", walls=WALLS, bounds=BOUNDS, tiles=tiles)


def _read(maze: Maze, poses, cfg: E.CameraConfig = VIEW):
    poses = jnp.asarray(poses, jnp.float32)
    world = E.compile_mazes([maze])
    return world, _camera(world, jnp.zeros(len(poses), jnp.int32), poses, cfg)


@pytest.mark.parametrize("colors", [4, pytest.param(5, marks=pytest.mark.slow), 6])
def test_a_tile_of_c_colours_shows_c_blobs_side_by_side(colors):
    world, cam = _read(_maze(Tile(4.2, 2.2, colors)), [FACING, (4.2, 0.6, -math.pi / 2)])
    assert world.n_blobs == colors
    assert np.asarray(cam.visible).shape == (2, 1, colors)
    assert np.asarray(cam.nearest).tolist() == [colors, 0]
    assert np.asarray(cam.blobs).tolist() == [colors, 0]
    assert np.asarray(cam.visible)[0, 0].all() and not np.asarray(cam.visible)[1].any()
    # blob 0 is the part on the u < 0 side (right of a robot facing along the heading), then
    # leftwards: the bearings (positive left) increase from blob to blob
    assert np.all(np.diff(np.asarray(cam.bearing)[0, 0]) > 0)
    under = E.tile_under(world, jnp.zeros(1, jnp.int32), jnp.asarray([[4.25, 2.2, math.pi / 2]]))
    assert np.asarray(under).tolist() == [colors]


@pytest.mark.slow
def test_the_segment_path_reads_tiles_of_many_colours_as_the_lattice(monkeypatch):
    maze = _maze(Tile(4.2, 2.2, 5), Tile(1.4, 4.2, 2, heading=0.0), Tile(4.2, 6.6, 6))
    poses = _poses(500, 1)
    world, lattice = _read(maze, poses)
    monkeypatch.setattr(E, "LATTICE_MAX_WORDS", 1)  # the same maze on the segment path
    segments, cam = _read(maze, poses)
    assert (world.mode, segments.mode) == ("lattice", "segments")
    assert world.n_blobs == segments.n_blobs == 6
    # two casters: a sample point grazing a wall may read apart
    assert (np.asarray(cam.visible) == np.asarray(lattice.visible)).all(axis=(1, 2)).mean() > 0.99
    assert (np.asarray(cam.nearest) == np.asarray(lattice.nearest)).mean() > 0.99
    assert {5, 6} <= set(np.asarray(cam.nearest).tolist())


def _aim(x: float, y: float, target: tuple[float, float]) -> tuple[float, float, float]:
    """The pose at ``(x, y)`` whose camera (behind the pose's centre) looks at ``target``."""
    theta = math.pi / 2
    for _ in range(20):
        cx = x + math.cos(theta) * E.CAMERA_POSITION[0]
        cy = y + math.sin(theta) * E.CAMERA_POSITION[0]
        theta = math.atan2(target[1] - cy, target[0] - cx)
    return (x, y, theta)


@pytest.mark.parametrize("colors", [4, pytest.param(5, marks=pytest.mark.slow), 6])
def test_each_part_of_a_tile_is_a_blob_of_its_own(colors):
    """A camera of a 2-degree field of view aimed at the middle of one part sees that blob
    alone (every part has a sample point of its own)."""
    width = 1.2
    # part k spans u in [-0.5 + k / c, -0.5 + (k + 1) / c]; u < 0 lies east of a northward tile
    centres = [-0.5 + (k + 0.5) / colors for k in range(colors)]
    poses = [_aim(4.2, 0.6, (4.2 - u * width, 2.2)) for u in centres]
    _, cam = _read(_maze(Tile(4.2, 2.2, colors)), poses, E.CameraConfig(fov_deg=2.0, range=3.5))
    np.testing.assert_array_equal(np.asarray(cam.visible)[:, 0], np.eye(colors, dtype=bool))
    assert np.asarray(cam.blobs).tolist() == [1] * colors
    assert np.asarray(cam.nearest).tolist() == [colors] * colors


def _poses(n: int, seed: int) -> np.ndarray:
    """Poses in the crossroad's arms, facing anywhere."""
    rng = np.random.default_rng(seed)
    along = rng.uniform(0.3, 8.1, n)
    across = rng.uniform(3.75, 4.65, n)
    vertical = rng.random(n) < 0.5
    return np.stack(
        [
            np.where(vertical, across, along),
            np.where(vertical, along, across),
            rng.uniform(-math.pi, math.pi, n),
        ],
        -1,
    )


def test_tiles_of_up_to_three_colours_read_the_same_beside_tiles_of_more():
    """The camera of a world with tiles of 4 to 6 colours reads its tiles of 1 to 3 colours
    exactly (visibility and bearing, bit for bit) as the camera of a world without them, which
    is the three-blob camera compiled as it always was (``n_blobs`` 3)."""
    few = (
        Tile(4.2, 2.2, 2),
        Tile(1.4, 4.2, 3, heading=0.0),
        Tile(4.2, 6.6, 1),
        Tile(4.2, 7.6, 3),
    )
    many = (*few, Tile(7.0, 4.2, 6, heading=0.0), Tile(6.0, 4.2, 4, heading=0.0))
    poses = _poses(4000, 0)
    plain_world, plain = _read(_maze(*few), poses)
    world, cam = _read(_maze(*many), poses)
    assert plain_world.n_blobs == 3 and np.asarray(plain.visible).shape == (4000, 4, 3)
    assert world.n_blobs == 6 and np.asarray(cam.visible).shape == (4000, 6, 6)
    visible, bearing = np.asarray(cam.visible), np.asarray(cam.bearing)
    np.testing.assert_array_equal(visible[:, :4, :3], np.asarray(plain.visible))
    if jax.default_backend() == "cpu":  # bit for bit (checked here; a GPU may fuse otherwise)
        assert bearing[:, :4, :3].tobytes() == np.asarray(plain.bearing).tobytes()
    np.testing.assert_allclose(bearing[:, :4, :3], np.asarray(plain.bearing), atol=1e-6)
    assert not visible[:, :4, 3:].any()
    assert np.asarray(plain.visible).any(-1).any(-1).mean() > 0.3  # most poses see a tile
    # where no tile of more colours is in view, the reading is the same
    apart = ~visible[:, 4:].any(axis=(-1, -2))
    assert apart.mean() > 0.5 and (~apart).mean() > 0.05
    np.testing.assert_array_equal(np.asarray(cam.nearest)[apart], np.asarray(plain.nearest)[apart])
    np.testing.assert_array_equal(np.asarray(cam.blobs)[apart], np.asarray(plain.blobs)[apart])
    assert set(np.asarray(cam.nearest)[~apart].tolist()) >= {4, 6}


def test_a_false_blob_reads_at_most_the_worlds_most_colours():
    nearest = jnp.asarray([0, 1, 2, 3, 4, 5, 6], jnp.int32)
    key = jax.random.key(0)
    always = NoiseConfig(camera_false=1.0)
    n, _ = camera_noise(nearest, nearest, always, key)
    assert np.asarray(n).tolist() == [1, 2, 3, 3, 4, 5, 6]  # at most 3, as always
    n, b = camera_noise(nearest, nearest, always, key, most=6)
    assert np.asarray(n).tolist() == [1, 2, 3, 4, 5, 6, 6]
    assert np.asarray(b).tolist() == [1, 2, 3, 4, 5, 6, 6]


@pytest.mark.parametrize(
    ("tiles", "want"),
    [
        ((Tile(4.2, 2.2, 4), Tile(1.2, 4.2, 6, heading=0.0)), 5),
        pytest.param((Tile(4.2, 2.2, 4),), 4, marks=pytest.mark.slow),
        pytest.param((Tile(4.2, 2.2, 3),), 3, marks=pytest.mark.slow),
        pytest.param((Tile(4.2, 2.2, 2),), 3, marks=pytest.mark.slow),
    ],
)
def test_a_false_blob_through_the_camera_reads_at_most_the_worlds_blob_count(tiles, want):
    """The cap is the world's ``n_blobs`` (3 for one of a 4-colour tile would lose the kind; 4
    there, 6 in a world that also has a 6-colour tile); a world of at most 3 colours, 3."""
    world = E.compile_mazes([_maze(*tiles)])
    mi = jnp.zeros(1, jnp.int32)
    mc = E.maze_constants(world, mi)
    place = locate(world, mc, jnp.asarray([FACING], jnp.float32))
    senses = Senses(camera=VIEW, noise=NoiseConfig(camera_false=1.0))
    reading = sense(world, mc, mi, place, senses, jax.random.key(1))
    assert int(reading.camera[0]) == want


def test_seven_colours_are_refused_in_one_line(tmp_path):
    assert TILE_COLORS == (1, 2, 3, 4, 5, 6)
    cases = [
        (lambda: Tile(1.0, 1.0, 7), r"^tile colors must be an integer from 1 to 6, got 7$"),
        (lambda: Tile(1.0, 1.0, 0), r"^tile colors must be an integer from 1 to 6, got 0$"),
        (
            lambda: parse_maze_text("#####\n#.7^#\n#####\n", "m.maze"),
            r"^m\.maze:2: unknown character '7' in column 3 \(expected one of "
            r"# \. 1 2 3 4 5 6 > < \^ v\)$",
        ),
        (
            lambda: parse_toml_maze(
                "[[wall]]\nxmin = 0\nxmax = 1\nymin = 0\nymax = 1\n"
                "[[tile]]\nx = 2\ny = 2\ncolors = 7\n",
                "b.toml",
            ),
            r"colors must be an integer from 1 to 6, got 7$",
        ),
        (
            lambda: crossroad("L", tile=7),
            r"^tile must be one of 1, 2, 3, 4, 5, 6 or None, got 7$",
        ),
        (
            lambda: fm.Family("seven", "x", tile_kinds=(1, 7), tile_rules=("right",) * 7),
            r"tile_kinds must be distinct colours among 1, 2, 3, 4, 5, 6, got \(1, 7\)$",
        ),
    ]
    for call, pattern in cases:
        with pytest.raises(MbnInputError, match=pattern) as caught:
            call()
        assert "\n" not in str(caught.value)


def test_a_maze_file_takes_tiles_of_four_to_six_colours():
    text = "cell = 1.5\n#########\n#.4.5.6v#\n#.#####.#\n#.......#\n#########\n"
    maze = parse_maze_text(text, "six.maze")
    assert [t.colors for t in maze.tiles] == [4, 5, 6]
    six = maze.tiles[2]
    assert (six.x, six.y, six.width) == pytest.approx((6.5 * 1.5, 3.5 * 1.5, 1.5))
    assert six.heading == 0.0  # across an east-west corridor
    assert crossroad("LSR", tile=6).tiles[0].colors == 6
    toml = parse_toml_maze(
        "[[wall]]\nxmin = 0\nxmax = 1\nymin = 0\nymax = 1\n[[tile]]\nx = 2\ny = 2\ncolors = 5\n",
        "five.toml",
    )
    assert toml.tiles[0].colors == 5


MANY = ("tiles4", "tiles5", "tiles6")
#: Seeds of each split (the test split is only ever a test: generated and checked, no more).
SEEDS = (0, 1, 1_000_000, 1_000_001, 2_000_000)


@pytest.mark.parametrize(
    "name", [*(pytest.param(n, marks=pytest.mark.slow) for n in MANY[:-1]), MANY[-1]]
)
def test_the_families_of_many_tile_kinds(name):
    kinds = int(name[-1])
    fam = fm.family(name)
    assert fam.tile_kinds == tuple(range(1, kinds + 1))
    assert fam.tile_rules == fm.MANY_TILE_RULES[:kinds]
    assert set(fam.tile_rules) <= set(fam.rules) and fam.first_rules == ("right", "left")
    assert name not in fm.ZERO_SHOT and fm._FAMILY_SALT[name] == kinds
    for seed in SEEDS:
        maze = fm.generate(name, seed)
        assert fm.check(maze, fam) == [], (name, seed)
        assert {t.colors for t in maze.tiles} == set(fam.tile_kinds)
        assert fm.describe(maze)["tiles"] == {str(k): 5 for k in fam.tile_kinds}
        places = fm.tile_places(maze)
        for kind in fam.tile_kinds:
            mine = [p for p in places if p["colors"] == kind]
            assert all(any(d in p["before"] for p in mine) for d in range(fam.reach + 1))
            assert any(p["mid"] for p in mine)
        for start in maze.starts:
            for first in fam.first_rules:
                route = rule_route(
                    maze,
                    tuple(start),
                    first,
                    fam.junctions,
                    follow_tiles=True,
                    count_from_tile=True,
                    tile_rules=fam.tile_rules,
                )
                assert route is not None
    # deterministic: made again from scratch, the same text
    text = fm.generate_text(name, 1_000_000)
    fm._generate.cache_clear()
    assert fm.generate_text(name, 1_000_000) == text
    assert parse_maze_text(text, "x.maze").tiles == fm.generate(name, 1_000_000).tiles


def test_a_maze_of_six_tile_kinds_is_drawn_with_every_kind_and_its_legend(tmp_path):
    from matplotlib.colors import to_hex

    from mbn.viz.maze import TILE_HATCHES, TILE_PALETTES, maze_legend_handles, save_maze_png

    maze = fm.generate("tiles6", 3)
    fig = save_maze_png(maze, tmp_path / "tiles6.png")
    assert (tmp_path / "tiles6.png").stat().st_size > 0
    (ax,) = fig.axes
    for n in range(1, 7):
        parts = [p for p in ax.patches if p.get_gid() == f"tile{n}"]
        assert len(parts) == n * sum(t.colors == n for t in maze.tiles) == 5 * n
        assert {to_hex(p.get_facecolor()) for p in parts} == set(TILE_PALETTES[n])
        assert {p.get_hatch() for p in parts} == {TILE_HATCHES.get(n)}
    handles = maze_legend_handles(maze, junctions=True, starts=True, tiles=True)
    labels = [(h[0] if isinstance(h, tuple) else h).get_label() for h in handles]
    words = ("one", "two", "three", "four", "five", "six")
    assert [f"{w}-colour tile" for w in words] == [x for x in labels if "tile" in x]
    assert [len(h) for h in handles if isinstance(h, tuple)] == [2, 3, 4, 5, 6]
