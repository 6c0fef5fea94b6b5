"""Import of Player/Stage world files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from mbn.errors import MbnInputError
from mbn.world.mazes.builtin import ARENA_WALLS
from mbn.world.mazes.load import load_maze
from mbn.world.mazes.stage import bitmap_grey, parse_stage_world, read_stage_world, tokenize

DATA = Path(__file__).resolve().parents[2] / "data" / "stage_world"


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def save_png(path: Path, grey_rows: list[list[int]]) -> None:
    """Save 8-bit grey levels as an RGB PNG (row 0 on top)."""
    grey = np.array(grey_rows, dtype=np.uint8)
    Image.fromarray(np.stack([grey] * 3, axis=-1), "RGB").save(path)


def test_tokenizer():
    text = 'define w model ( size [1 -2.5e1 .5] ) # comment\npoint[0] "a b"\n'
    tokens = tokenize(text, "f.world")
    assert [(t.kind, t.value, t.line) for t in tokens] == [
        ("word", "define", 1),
        ("word", "w", 1),
        ("word", "model", 1),
        ("punct", "(", 1),
        ("word", "size", 1),
        ("punct", "[", 1),
        ("number", "1", 1),
        ("number", "-2.5e1", 1),
        ("number", ".5", 1),
        ("punct", "]", 1),
        ("punct", ")", 1),
        ("word", "point[0]", 2),
        ("string", "a b", 2),
    ]
    assert tokens[-1].where == "f.world:2"


def test_arena_world_reproduces_the_reference_arena():
    maze = read_stage_world(DATA / "arena.world")
    np.testing.assert_array_equal(maze.walls, ARENA_WALLS)
    assert maze.bounds == (0.0, 14.0, 0.0, 10.4) and not maze.outside_is_wall
    assert maze.name == "arena" and maze.grid is None
    np.testing.assert_allclose(maze.starts, [[2.2, 5.2, 0.0], [4.6, 2.2, math.pi / 2]])
    same = load_maze(DATA / "arena.world")
    np.testing.assert_array_equal(same.walls, maze.walls)


def test_bitmap_floorplan_gives_its_dark_pixels_as_rectangles():
    # plus4.png:  ##.#  /  #...  /  #..#  /  ####   (row 0 north), 2 m pixels over [0, 8]^2
    maze = read_stage_world(DATA / "bitmap.world")
    np.testing.assert_allclose(
        maze.walls,
        [[0, 4, 6, 8], [6, 8, 6, 8], [0, 2, 2, 6], [6, 8, 2, 4], [0, 8, 0, 2]],
    )
    np.testing.assert_allclose(maze.starts, [[4.0, 4.0, 0.0]])
    assert maze.bounds == (0.0, 8.0, 0.0, 8.0)


def test_bitmap_grey_levels_of_the_test_floorplan():
    # plus4.png is RGBA; grey is the mean of R, G, B on 0..255, alpha ignored
    np.testing.assert_array_equal(
        bitmap_grey(DATA / "plus4.png"),
        [[20, 20, 255, 20], [20, 255, 255, 255], [20, 255, 255, 20], [20, 20, 20, 20]],
    )


@pytest.mark.parametrize("mode", ["1", "L", "LA", "P", "RGB", "RGBA", "I;16"])
def test_bitmap_grey_of_every_png_mode(tmp_path: Path, mode: str):
    levels = np.array([[0, 127, 128, 255]], dtype=np.uint8)
    rgb = Image.fromarray(np.stack([levels] * 3, axis=-1), "RGB")
    if mode == "I;16":
        image = Image.fromarray(levels.astype(np.uint16) * 257)
        assert image.mode == "I;16"
    elif mode == "1":
        image = rgb.convert("L").point(lambda v: 255 * (v > 127)).convert("1")
    elif mode == "P":
        image = rgb.quantize(colors=4)  # a palette of exactly the four levels
    else:
        image = rgb.convert(mode)
    image.save(tmp_path / "m.png")
    want = [[0, 0, 255, 255]] if mode == "1" else levels
    np.testing.assert_array_equal(bitmap_grey(tmp_path / "m.png"), want)


def test_bitmap_threshold_pixel_shape_and_extent(tmp_path: Path):
    # grey 127 is an obstacle, 128 is not; the dark pixels span columns 1..2 and rows 0..1
    save_png(tmp_path / "m.png", [[255, 127, 0, 255], [255, 128, 10, 255], [255, 255, 255, 255]])
    body = 'bitmap "m.png" size [ 6 2 0.5 ] pose [ 10 20 0 0 ]'
    maze = parse_stage_world(f"model( {body} )", tmp_path / "a.world")
    # dark bounding box (2 x 2 pixels) stretched over 6 x 2 m: 3 m x 1 m pixels, centred (10, 20)
    np.testing.assert_allclose(maze.walls, [[7, 13, 20, 21], [10, 13, 19, 20]])
    image = parse_stage_world(f"model( {body} )", tmp_path / "a.world", bitmap_extent="image")
    # the whole 4 x 3 image over 6 x 2 m: 1.5 m x 2/3 m pixels
    np.testing.assert_allclose(
        image.walls, [[8.5, 11.5, 20 + 1 / 3, 21], [10.0, 11.5, 20 - 1 / 3, 20 + 1 / 3]]
    )


def test_bitmap_rotation_boundary_and_origin(tmp_path: Path):
    save_png(tmp_path / "bar.png", [[0, 0, 0, 0], [0, 255, 255, 255]])  # a bar with a stub
    text = 'model( bitmap "bar.png" size [ 4 2 1 ] pose [ 0 0 0 90 ] )'
    maze = parse_stage_world(text, tmp_path / "r.world")
    # unrotated: bar y in [0, 1] x in [-2, 2], stub x in [-2, -1] y in [-1, 0];
    # rotated 90 deg CCW: (x, y) -> (-y, x)
    got = sorted(map(tuple, np.round(maze.walls, 9).tolist()))
    assert got == [(-1.0, 0.0, -2.0, 2.0), (0.0, 1.0, -2.0, -1.0)]
    boxed = parse_stage_world(
        'model( bitmap "bar.png" size [ 4 2 1 ] pose [ 0 0 0 0 ] origin [ 1 0 0 0 ] boundary 1 )',
        tmp_path / "b.world",
    )
    w = boxed.walls
    assert len(w) == 2 + 4
    # the footprint is shifted by origin x = 1: [-1, 3] x [-1, 1]; thin boundary walls 0.01 px
    assert (w[:, 0].min(), w[:, 1].max(), w[:, 2].min(), w[:, 3].max()) == (-1, 3, -1, 1)
    np.testing.assert_allclose(sorted(w[-4:, 1] - w[-4:, 0])[:2], [0.01, 0.01])


def test_rotated_nested_and_skipped_models(tmp_path: Path):
    text = """
    define box model ( size [ 2 1 1 ] )
    define ghost model ( obstacle_return 0 )
    box( pose [ 5 5 0 90 ] )                 # extents swapped: 1 x 2
    box( pose [ 0 0 0 -180 ] )               # 180 deg: unchanged
    ghost( pose [ 9 9 0 0 ] size [ 1 1 1 ] ) # the robot passes through it in Stage
    model( size [ 1 1 1 ] )                  # no pose: skipped
    model( pose [ 10 0 0 90 ]                # a group without size, rotated
      box( pose [ 2 0 0 0 ] )                # placed at (10, 2), rotated 90 deg: 1 x 2
    )
    """
    maze = parse_stage_world(text, tmp_path / "n.world")
    np.testing.assert_allclose(
        maze.walls, [[4.5, 5.5, 4, 6], [-1, 1, -0.5, 0.5], [9.5, 10.5, 1, 3]]
    )


def test_includes_are_relative_to_the_including_file(tmp_path: Path):
    write(tmp_path, "lib/robots.inc", 'include "walls.inc"\ndefine bot position ( )\n')
    write(tmp_path, "lib/walls.inc", "define wall model ( size [ 1 1 1 ] )\n")
    path = write(
        tmp_path,
        "w.world",
        'include "lib/robots.inc"\nwall( pose [ 0 0 0 0 ] )\nbot( pose [ 3 0 0 180 ] )\n',
    )
    maze = read_stage_world(path)
    np.testing.assert_allclose(maze.walls, [[-0.5, 0.5, -0.5, 0.5]])
    np.testing.assert_allclose(maze.starts, [[3.0, 0.0, math.pi]])
    assert maze.bounds == (-0.5, 3.0, -0.5, 0.5)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "model( size [ 1 1 1 ] pose [ 0 0 0 45 ] )",
            "e.world:1: pose rotation 45 deg is not a multiple of 90",
        ),
        (
            "model( size [ 1 1 1 ]\n origin [ 0 0 0 30 ] pose [ 0 0 0 0 ] )",
            "e.world:2: origin rotation 30 deg",
        ),
        ('include "nowhere.inc"', "e.world:1: include file 'nowhere.inc' not found"),
        ('model( name "x )', "e.world:1: unterminated string"),
        ("model( size [ 1 1 1 ] pose [ 0 0 0 0 ]", "unexpected end of file (expected ')')"),
        ("model( size [ 1 1 1 ) )", "e.world:1: unexpected ')' in the tuple of size"),
        (
            "model( size )",
            "e.world:1: expected a number, a \"string\" or a [tuple] after size, got ')'",
        ),
        ("model( size [ 1 1 1 ] pose [ 0 ] )", "e.world:1: pose needs 2 to 4 numbers, got 1"),
        (
            "model( size [ 1 x 1 ] pose [ 0 0 ] )",
            "e.world:1: size must hold finite numbers, got 'x'",
        ),
        ("model( size [ 0 1 1 ] pose [ 0 0 ] )", "e.world:1: size must be > 0"),
        ("model( 3 )", "e.world:1: expected a property name, a model or ')', got '3'"),
        ('model( bitmap "none.png" size [ 1 1 ] )', "e.world:1: bitmap file 'none.png' not found"),
        ("resolution 0.02\n", "e.world: the world has no walls"),
        (
            "define a b ( )\ndefine b a ( )\na( pose [ 0 0 ] size [ 1 1 ] )",
            "e.world:3: the definition of type 'a' is circular",
        ),
        ("$", "e.world:1: unexpected character '$'"),
        (
            'model( pose [ 0 0 0 0 ] size [ 4 4 1 ] )\nposition( name "r2" pose [ 1 0 0 0 ] )',
            "e.world:2: robot 'r2' (start #1) at (1, 0, 0 deg): the robot's body overlaps a wall",
        ),
    ],
)
def test_world_errors_name_file_and_line(tmp_path: Path, text: str, message: str):
    with pytest.raises(MbnInputError) as info:
        parse_stage_world(text, tmp_path / "e.world")
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_bad_bitmap_file(tmp_path: Path):
    write(tmp_path, "junk.png", "not a png")
    with pytest.raises(MbnInputError, match=r"e\.world:1: cannot read bitmap"):
        parse_stage_world('model( bitmap "junk.png" size [ 1 1 ] )', tmp_path / "e.world")
