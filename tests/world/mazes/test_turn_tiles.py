"""The families of the switch, ``turns2`` .. ``turns6``: the tiles of ``tiles2`` .. ``tiles6`` at
every distance 0 .. 3 before a junction and on corners (``Family.turn_tiles``), so that the
program changes in the middle of a turn; the camera reads a corner's tile from either arm, a
walk puts it in force as the rollout does, the families of before draw exactly what they drew,
and a family asking for corner tiles its layout cannot give is refused in one line."""

from __future__ import annotations

import hashlib
import math
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.world import engine as E  # noqa: N812
from mbn.world.junctions import STEPS, RoutePass, cell_of, decision_cells, route_passes
from mbn.world.mazes import families as fm
from mbn.world.mazes.families import Family
from mbn.world.mazes.grid_text import parse_maze_text

TURNS = ("turns2", "turns3", "turns4", "turns5", "turns6")
#: turns6 (six tile kinds, the most) is checked with the slow tests; turns2-5 in every run.
TURNS_IN_CI = [*TURNS[:-1], pytest.param(TURNS[-1], marks=pytest.mark.slow)]
#: Seeds of each split (the test split is only ever a test: generated and checked, no more).
SEEDS = (0, 1, 1_000_000, 1_000_001, 2_000_000)
#: The camera the MBNs are trained and tested with (``docs/reproduce.md``) and the world's.
NEAR, FAR = E.CameraConfig(range=0.8), E.CameraConfig()

#: sha256 of ``generate_text`` of the families of before: the maze texts they gave before
#: corner tiles existed (seeds of each split).
FINGERPRINTS = {
    "grid:0": "6d6785c489a3497b915eb71f8aa8cd9130046ef0d739fd1eed18730d40cc4292",
    "grid:1000000": "5d8421b06863da3daacf4b56459a122ce4518ee03fe4429592647e7141508b94",
    "tiles2:0": "8ca786886110a78ea39985ce69186629ede45f7a2ccf79ea7dc73d19b7f956dc",
    "tiles3:1000000": "f01357ce4eff67ca02eb75750030e4133a3ba755e278042d5275c4ba76fdd7cb",
    "tiles4:2000000": "1539af6db2645de0e8a775a9046f108374dbf6a054848f174163b86d29d5eedd",
    "tiles5:1": "081a967537b4198b39cd2236b71d8708d642750cdd2c83de9186c7d4953c6578",
    "tiles6:1000001": "7746a438b112cebf43b4e7e63598236a52cef67df2cee2d7a941165a28cb80b0",
}


@pytest.mark.parametrize("name", TURNS)
def test_the_turns_families_are_the_tiles_families_with_a_tile_of_each_kind_on_a_corner(name):
    kinds = int(name[-1])
    fam, tiles = fm.family(name), fm.family(f"tiles{kinds}")
    for key in ("tile_kinds", "tile_rules", "first_rules", "rules", "junctions", "starts"):
        assert getattr(fam, key) == getattr(tiles, key), key
    assert fam.reach == 3 and fam.near_tiles == 4 and fam.mid_tiles == 1
    assert fam.turn_tiles == 1 and tiles.turn_tiles == 0
    assert fam.size[0] >= tiles.size[0] and fam.size[1] >= tiles.size[1]
    assert name not in fm.ZERO_SHOT and fm._FAMILY_SALT[name] == 5 + kinds
    assert fm.family_splits(name) == fm.SPLITS
    assert fam.to_dict()["turn_tiles"] == 1 and "turn_tiles" not in tiles.to_dict()


def test_the_salts_of_the_families_are_distinct():
    salts = [fm._FAMILY_SALT[n] for n in ("grid", *(f"tiles{k}" for k in range(2, 7)), *TURNS)]
    assert len(set(salts)) == len(salts)


@pytest.mark.parametrize("name", TURNS_IN_CI)
def test_every_maze_has_every_kind_at_every_distance_and_on_a_corner(name):
    fam = fm.family(name)
    for seed in SEEDS:
        maze = fm.generate(name, seed)
        assert fm.check(maze, fam) == [], (name, seed)
        free = np.asarray(maze.grid) != "#"
        corners = fm.corner_cells(free)
        places = fm.tile_places(maze)
        assert {p["colors"] for p in places} == set(fam.tile_kinds)
        for kind in fam.tile_kinds:
            mine = [p for p in places if p["colors"] == kind]
            straight = [p for p in mine if not p["corner"]]
            for d in range(4):
                assert any(d in p["before"] for p in straight), (name, seed, kind, d)
            assert any(p["mid"] for p in straight), (name, seed, kind)
            assert sum(p["turn"] for p in mine) >= 1, (name, seed, kind)
        held = {cell_of(maze, t.x, t.y) for t in maze.tiles}
        for tile, place in zip(maze.tiles, places, strict=True):
            r, c = cell_of(maze, tile.x, tile.y)
            assert place["corner"] == bool(corners[r, c])
            if place["corner"]:
                # a corner, a T or plus crossing along one of its arms, no tile between
                assert place["turn"] and fm.turn_leads(free, r, c, held)
            # no two tiles side by side
            assert all((r + dr, c + dc) not in held for dr, dc in STEPS)


@pytest.mark.parametrize("name", ["turns2", pytest.param("turns6", marks=pytest.mark.slow)])
def test_the_generation_is_deterministic_and_reads_back(name):
    text = fm.generate_text(name, 1_000_000)
    fm._generate.cache_clear()  # made again from scratch, not read from the cache
    assert fm.generate_text(name, 1_000_000) == text
    assert fm.generate_text(name, 1_000_001) != text
    assert parse_maze_text(text, "x.maze").tiles == fm.generate(name, 1_000_000).tiles
    assert "turn" in text.splitlines()[2]  # the record of where the tiles lie


def test_the_families_of_before_give_the_mazes_they_gave():
    for key, digest in FINGERPRINTS.items():
        name, seed = key.split(":")
        text = fm.generate_text(name, int(seed))
        assert hashlib.sha256(text.encode()).hexdigest() == digest, key
    # and nothing of corner tiles reaches their record of where the tiles lie
    for k in range(2, 7):
        assert "turn" not in fm.generate_text(f"tiles{k}", 1_000_000)


def test_the_check_refuses_a_maze_without_its_corner_tiles():
    fam = fm.family("turns2")
    maze = fm.generate("turns2", 1_000_000)
    text = fm.generate_text("turns2", 1_000_000)
    lines = text.splitlines()
    grid_start = next(i for i, line in enumerate(lines) if line.startswith("#"))
    for tile, place in zip(maze.tiles, fm.tile_places(maze), strict=True):
        if place["corner"] and place["colors"] == 1:
            r, c = cell_of(maze, tile.x, tile.y)
            row = lines[grid_start + r]
            lines[grid_start + r] = row[:c] + "." + row[c + 1 :]
    bare = parse_maze_text("\n".join(lines) + "\n", "bare.maze")
    assert "fewer than 1 1-colour tiles on a corner before a junction" in fm.check(bare, fam)
    # a maze of tiles2 (no corner tile) is no maze of turns2
    problems = fm.check(fm.generate("tiles2", 1_000_000), fam)
    assert "fewer than 1 2-colour tiles on a corner before a junction" in problems


def ring(fam: Family, rng: np.random.Generator) -> np.ndarray:
    """A ring of corridors: four corners, no junction."""
    free = np.zeros((7, 7), bool)
    free[1, 1:6] = free[5, 1:6] = free[1:6, 1] = free[1:6, 5] = True
    return free


def test_a_family_whose_layout_has_no_corner_before_a_junction_is_refused_in_one_line():
    fam = Family(
        "rings",
        "a ring: corners, no junction",
        layout=ring,
        tile_kinds=(1, 2),
        tile_rules=("right", "left"),
        first_rules=("right",),
        rules=("right",),
        near_tiles=0,
        mid_tiles=0,
        turn_tiles=1,
        starts=1,
        junctions=1,
    )
    with pytest.raises(MbnInputError) as err:
        fm.generate(fam, 0)
    message = str(err.value)
    assert "\n" not in message
    assert "no corner with a T or plus crossing along an arm for a 1-colour tile" in message
    assert "maze family 'rings': no valid maze for seed 0" in message


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"turn_tiles": -1}, "turn_tiles must be an integer >= 0"),
        ({"turn_tiles": 1.5}, "turn_tiles must be an integer >= 0"),
        ({"tile_kinds": (), "tile_rules": (), "first_rules": ()}, "turn_tiles needs tile_kinds"),
    ],
)
def test_bad_corner_tile_parameters_are_refused_in_one_line(changes, message):
    with pytest.raises(MbnInputError, match=message) as err:
        fm.family("turns2").replace(**changes)
    assert "\n" not in str(err.value)


# --------------------------------------------------------------------------------------------
# A corner's tile: what the camera reads of it, and when it is in force
# --------------------------------------------------------------------------------------------


@partial(jax.jit, static_argnums=3)
def _camera(world: E.World, maze_index: jax.Array, p: jax.Array, cfg: E.CameraConfig):
    mc = E.maze_constants(world, maze_index)
    words, ci, cj = E.window_words(world, mc, p[:, 0], p[:, 1])
    return E.see_tiles(world, mc, maze_index, words, ci, cj, p, cfg)


def _read(maze, poses, cfg: E.CameraConfig):
    world = E.compile_mazes([maze])
    p = jnp.asarray(poses, jnp.float32)
    return world, _camera(world, jnp.zeros(len(poses), jnp.int32), p, cfg)


def _corner(colors: int) -> str:
    """A corner (row 1, column 5) with a tile, its arms west and south."""
    return f"cell = 1.2\n#######\n#....{colors}#\n#####.#\n#####.#\n#####.#\n#######\n"


@pytest.mark.parametrize(
    "colors", [1, 2, 3, *(pytest.param(c, marks=pytest.mark.slow) for c in (4, 5, 6))]
)
def test_a_corner_tile_shows_all_its_colours_from_either_arm(colors):
    """Laid as the grid lays a tile in a cell with one free neighbour each way: heading north
    (across the east-west arm, along the north-south one), a cell wide, at the cell's centre.
    From the south arm its parts lie side by side across the view, from the west arm one behind
    the other along it: from either, the nearest tile in view reads its colours and all its
    blobs are in view."""
    maze = parse_maze_text(_corner(colors), "corner.maze")
    (tile,) = maze.tiles
    assert tile.heading == pytest.approx(math.pi / 2) and tile.width == maze.cell
    x, y = tile.x, tile.y
    poses = [(x - d, y, 0.0) for d in (2.4, 1.2)] + [(x, y - d, math.pi / 2) for d in (2.4, 1.2)]
    _, cam = _read(maze, poses, FAR)
    assert np.asarray(cam.nearest).tolist() == [colors] * 4
    assert np.asarray(cam.blobs).tolist() == [colors] * 4
    # the MBNs' camera (0.8 m): the tile's colours as the robot's front comes into the corner
    # from either arm (and its parts one by one from the west, the nearest first)
    near = [(x - 0.7, y, 0.0), (x, y - 0.7, math.pi / 2)]
    _, cam = _read(maze, near, NEAR)
    assert np.asarray(cam.nearest).tolist() == [colors, colors]
    assert min(np.asarray(cam.blobs).tolist()) >= 1
    # facing away, or from a cell back with the short camera: nothing
    _, cam = _read(maze, [(x - 2.4, y, math.pi), (x - 2.4, y, 0.0)], NEAR)
    assert np.asarray(cam.nearest).tolist() == [0, 0]


def test_a_corner_tile_covers_the_whole_corner():
    """On a corner the grid lays a tile a cell long, so that the middle of the body is on it
    wherever the robot crosses the cell, however it cuts the corner; elsewhere 0.3 m long."""
    maze = parse_maze_text(
        _corner(2).replace("#####.#\n#####.#\n#######", "#####2#\n#####.#\n#######"), "c"
    )
    corner, straight = sorted(maze.tiles, key=lambda t: -t.y)
    assert corner.length == maze.cell and straight.length == pytest.approx(0.3)
    world = E.compile_mazes([maze])
    x, y = corner.x, corner.y
    offset = E.CAMERA_POSITION[0]  # the middle of the body, behind the pose
    points = [
        (x + dx, y + dy) for dx in (-0.55, -0.3, 0.3, 0.55) for dy in (-0.55, -0.3, 0.3, 0.55)
    ]
    poses = jnp.asarray([(px - offset, py, 0.0) for px, py in points], jnp.float32)
    under = E.tile_under(world, jnp.zeros(len(points), jnp.int32), poses)
    assert np.asarray(under).tolist() == [2] * len(points)


@pytest.mark.parametrize("name", ["turns3", pytest.param("turns6", marks=pytest.mark.slow)])
def test_every_corner_tile_of_a_maze_is_read_from_each_arm(name):
    """In a generated maze, a robot one cell out along either arm of a corner with a tile,
    facing the corner, reads the tile's colours and all its blobs."""
    maze = fm.generate(name, 1_000_000)
    free = np.asarray(maze.grid) != "#"
    rows = free.shape[0]
    poses, expected = [], []
    for tile, place in zip(maze.tiles, fm.tile_places(maze), strict=True):
        if not place["corner"]:
            continue
        r, c = cell_of(maze, tile.x, tile.y)
        for h, (dr, dc) in enumerate(STEPS):
            if free[r + dr, c + dc]:
                x, y = (c + dc + 0.5) * maze.cell, (rows - 1 - (r + dr) + 0.5) * maze.cell
                facing = {0: -math.pi / 2, 1: math.pi, 2: math.pi / 2, 3: 0.0}[h]
                poses.append((x, y, facing))
                expected.append(tile.colors)
    assert len(expected) >= 2 * len(fm.family(name).tile_kinds)
    _, cam = _read(maze, poses, FAR)
    assert np.asarray(cam.nearest).tolist() == expected
    assert np.asarray(cam.blobs).tolist() == expected


def test_a_corner_tile_is_in_force_after_the_corners_pass_in_a_walk_and_a_rollout():
    """A walk (``route_passes``) judges the corner's pass by the rule in force on entry and the
    next junction by the corner tile's, as a rollout records them: the tile in force when the
    robot moves into the corner's cell (``junction_tile``) is the one before it, the middle of
    the body (where the tile under the robot is read) not yet on the corner's tile, from either
    arm; at the corner's centre it is the corner's."""
    maze = parse_maze_text(
        "cell = 1.2\n"
        "########\n"
        "#2.....#\n"  # a corner with a two-colour tile, then a T junction (row 1, column 4)
        "#.##.#.#\n"
        "#.##.#.#\n"
        "#^##...#\n"  # the start faces north, up to the corner
        "#.######\n"
        "########\n",
        "corner_then_t",
    )
    start = tuple(maze.starts[0])
    assert decision_cells(maze)[1, 1] and decision_cells(maze)[1, 4]
    rules = ("right", "left")
    assert route_passes(maze, start, "right", 2, follow_tiles=True, tile_rules=rules) == [
        RoutePass("right", 0, frozenset({"right", "back"})),  # the corner: right on entry
        RoutePass("left", 2, frozenset({"straight", "right", "back"})),  # then the tile's
    ]
    # judged from the first tile: the corner's pass is not among them (as the rollout's, whose
    # tile in force on entry into the corner is none yet)
    assert route_passes(
        maze, start, "right", 1, follow_tiles=True, count_from_tile=True, tile_rules=rules
    ) == [RoutePass("left", 2, frozenset({"straight", "right", "back"}))]
    (tile,) = maze.tiles
    x, y = tile.x, tile.y
    inside = 0.5 * maze.cell - 0.01  # the pose 1 cm into the corner's cell
    world = E.compile_mazes([maze])
    poses = jnp.asarray(
        [(x, y - inside, math.pi / 2), (x + inside, y, math.pi), (x, y, math.pi / 2), (x, y, 0.0)],
        jnp.float32,
    )
    under = E.tile_under(world, jnp.zeros(4, jnp.int32), poses)
    assert np.asarray(under).tolist() == [0, 0, 2, 2]
