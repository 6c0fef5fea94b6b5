"""A maze family and a maze format of your own, defined here, outside ``mbn``: registered, they
are generated, named, split and selected as the built-in ones are (``register_family``,
``register_format``); a bad registration is refused in one line naming what is wrong."""

from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.experiments.maze_task import MazeTask
from mbn.experiments.stages.common import tile_family, validation_maze_names
from mbn.experiments.stages.settings import EpisodeSettings, ValidationSettings
from mbn.world.junctions import decision_cells, free_neighbours
from mbn.world.mazes import families as fm
from mbn.world.mazes.families import Family, RetryError, register_family
from mbn.world.mazes.grid_text import parse_maze_text
from mbn.world.mazes.load import load_maze, load_mazes, maze_suffixes, register_format
from mbn.world.mazes.model import Maze
from tests.registries import isolate

#: The ladder's own splits of generator seeds.
SPLITS = {"train": range(0, 1000), "validation": range(5000, 5010), "test": range(9000, 9020)}


def ladder(fam: Family, rng: np.random.Generator) -> np.ndarray:
    """Two rails joined by rungs ``gap`` cells apart: corners and T junctions, no plus crossing
    (which the lattice's checks would ask for)."""
    cols = int(rng.integers(fam.size[0], fam.size[1] + 1))
    free = np.zeros((7, cols), bool)
    free[1, 1 : cols - 1] = free[5, 1 : cols - 1] = True
    rungs = [1]
    while rungs[-1] + fam.gap[0] < cols - 2:
        rungs.append(rungs[-1] + int(rng.integers(fam.gap[0], fam.gap[1] + 1)))
    rungs[-1] = cols - 2
    if rungs[-1] - rungs[-2] < 2:
        raise RetryError("two rungs side by side")
    for c in rungs:
        free[1:6, c] = True
    return free


def ladder_family(name: str = "ladder", **changes) -> Family:
    """Tiles of one colour put right in force, of two colours right-left."""
    fam = Family(
        name,
        "two rails and rungs, the tiles right and right-left",
        size=(15, 21),
        gap=(3, 5),
        layout=ladder,
        tile_kinds=(1, 2),
        reach=1,
        near_tiles=2,
        mid_tiles=0,
        starts=4,
        rules=("right", "right-left"),
        first_rules=("right",),
        tile_rules=("right", "RLS"),  # an order is kept as its name
        splits=SPLITS,
    )
    return fam.replace(**changes) if changes else fam


@pytest.fixture
def own(monkeypatch):
    """The test's registrations stay in the test."""
    isolate(monkeypatch)


def test_an_own_family_is_registered_generated_and_checked(own):
    with pytest.raises(MbnInputError, match=r"^unknown maze family 'ladder' \(known: grid, "):
        fm.generate("ladder", 3)
    fam = register_family(ladder_family())
    assert fm.family("ladder") is fam and list(fm.FAMILIES)[-1] == "ladder"
    assert fam.tile_rules == ("right", "right-left")
    assert register_family(ladder_family()) is fam  # the same again: a module imported twice
    text = fm.generate_text("ladder", 3)
    fm._generate.cache_clear()
    assert fm.generate_text("ladder", 3) == text  # the seed alone makes it
    assert fm.generate_text("ladder", 4) != text
    assert "; split train;" in text and "name = ladder:3" in text
    maze = fm.generate("ladder", 3)
    grid = np.asarray(maze.grid)
    assert grid.shape[0] == 7 and set(grid[3]) <= {"#", ".", "1", "2", "^", "v", "<", ">"}
    # its own layout: T junctions and corners, no plus crossing, and still a maze of the family
    count = np.where(grid != "#", free_neighbours(maze).sum(-1), 0)
    assert (count == 3).any() and not (count == 4).any() and decision_cells(maze).any()
    assert fm.check(maze, fam) == [] and len(maze.starts) == 4
    assert {t.colors for t in maze.tiles} == {1, 2}
    # the same text as a file reads back as the same maze
    again = parse_maze_text(text, "ladder:3")
    assert np.array_equal(np.asarray(again.grid), grid)
    assert fm.describe(maze)["plus_crossings"] == 0


def test_its_splits_name_and_select_its_mazes(own):
    register_family(ladder_family())
    # names: one maze, a split, part of one
    assert load_maze("ladder:5001").name == "ladder:5001"
    mazes, split = load_mazes("ladder/validation:0-2")
    assert split == "ladder/validation:0-2" and [m.name for m in mazes] == [
        "ladder:5000",
        "ladder:5001",
        "ladder:5002",
    ]
    assert len(load_mazes("ladder/test")[0]) == 20
    assert fm.split_seeds("test", fam="ladder") == list(range(9000, 9020))
    # its test split is only ever a test; a seed outside its splits is no maze of it
    with pytest.raises(MbnInputError, match="maze seed 9001 is in the test split"):
        fm.check_use([9001], "validation", fam="ladder")
    with pytest.raises(MbnInputError, match=r"maze seed 2000000 is in no split \(train 0-999"):
        load_maze("ladder:2000000")
    with pytest.raises(MbnInputError, match="the family 'ladder' has no zero-shot suite"):
        load_mazes("ladder/zero-shot")
    # the settings that select a built-in family select it
    assert EpisodeSettings(kind="maze", family="ladder").family == "ladder"
    task = MazeTask(rule="right", family="ladder", pool=6, mazes=2, starts=2, seed=4)
    assert all(s in SPLITS["train"] for s in task.pool_seeds())
    arrays = task.arrays()
    assert len(arrays.mazes) == 6 and arrays.mazes[0].name.startswith("ladder:")
    # an MBN whose tiles put right and right-left in force is validated in its mazes
    assert tile_family(("right", "right-left")) == "ladder"
    assert tile_family(("right", "left")) == "tiles2"  # the built-ins keep theirs
    sections = {
        "episodes": EpisodeSettings(kind="maze"),
        "validation": ValidationSettings(split_mazes=3),
    }
    ctx = SimpleNamespace(section=lambda cls: sections[cls.section])
    names = validation_maze_names(ctx, "tiles", tile_rules=("right", "RLS"))
    assert names == ["ladder:5000", "ladder:5001", "ladder:5002"]


def test_without_it_an_mbn_of_those_rules_has_no_family(own):
    with pytest.raises(MbnInputError) as caught:
        tile_family(("right", "right-left"))
    message = str(caught.value)
    assert message.startswith("no maze family has tiles for the rules right, right-left")
    assert "register_family" in message and "\n" not in message
    with pytest.raises(MbnInputError, match=r"^episodes\.family: expected one of grid, tiles2"):
        EpisodeSettings(kind="maze", family="ladder")


def test_the_built_in_families_are_registered_as_an_own_one_is():
    # the same path: a built-in registered again is the same family
    for name in ("grid", "tiles2", "tiles3"):
        fam = fm.family(name)
        assert register_family(fam, zero_shot=fm.ZERO_SHOT[name], salt=fm._FAMILY_SALT[name])
        assert fam.layout is None and fam.splits is None  # the lattice, the shared splits
        if name not in fm.LOOKED_INTO:  # tiles3's test mazes looked into: test_families.py
            assert fm.family_splits(name) is fm.SPLITS
    assert fm._FAMILY_SALT == {
        "grid": 1,
        "tiles2": 2,
        "tiles3": 3,
        "tiles4": 4,
        "tiles5": 5,
        "tiles6": 6,
        "turns2": 7,
        "turns3": 8,
        "turns4": 9,
        "turns5": 10,
        "turns6": 11,
    }
    assert "layout" not in fm.family("grid").to_dict()  # their record is as it was


def _refused(call, pattern: str) -> None:
    with pytest.raises(MbnInputError) as caught:
        call()
    message = str(caught.value)
    assert "\n" not in message, message
    assert re.search(pattern, message), message


def test_a_bad_family_is_refused_in_one_line(own):
    register_family(ladder_family())
    _refused(
        lambda: register_family(ladder_family(starts=3)),
        r"register_family\('ladder'\): another family of that name is registered already",
    )
    _refused(
        lambda: register_family(ladder_family("Ladder-2")),
        r"register_family\('Ladder-2'\): a family's name is lower-case letters, digits and '_'",
    )
    _refused(
        lambda: register_family(ladder_family("grid")),
        r"register_family\('grid'\): another family of that name",
    )
    _refused(lambda: register_family("ladder"), r"register_family: expected a Family, got str")
    _refused(
        lambda: ladder_family("other", tile_rules=("right", "sideways")),
        r"^maze family 'other': tile_rules: unknown rule 'sideways'",
    )
    _refused(
        lambda: ladder_family("other", splits={"train": range(10), "test": range(20, 30)}),
        r"^maze family 'other': splits must map train, validation and test to ranges of seeds",
    )
    _refused(
        lambda: ladder_family(
            "other",
            splits={"train": range(100), "validation": range(50, 60), "test": range(200, 210)},
        ),
        r"^maze family 'other': splits: train and validation overlap",
    )
    _refused(
        lambda: ladder_family("other", layout="ladder"),
        r"^maze family 'other': layout must be a function",
    )
    _refused(
        lambda: register_family(ladder_family("other"), zero_shot=("nowhere",)),
        r"register_family\('other'\): zero_shot: 'nowhere' is not a built-in maze",
    )
    _refused(
        lambda: register_family(ladder_family("other"), salt=-1),
        r"register_family\('other'\): salt must be an integer >= 0",
    )
    # a layout that gives no mask, or leaves the outer ring open, is named when it runs
    register_family(ladder_family("open_ring", layout=lambda fam, rng: np.ones((9, 9), bool)))
    _refused(
        lambda: fm.generate("open_ring", 1),
        r"^maze family 'open_ring': its layout left a free cell on the outer ring",
    )
    register_family(ladder_family("listed", layout=lambda fam, rng: [[True]]))
    _refused(
        lambda: fm.generate("listed", 1),
        r"^maze family 'listed': its layout must give a 2-D boolean NumPy array .* got list$",
    )


# --- a maze format of your own -------------------------------------------------------------


def read_rows(path: Path):
    """A ``.rows`` file: ``cell`` on its first line, then the grid with ``o`` for free cells
    and ``x`` for walls (start marks and tile digits as in a ``.maze``)."""
    cell, *rows = Path(path).read_text().split()
    text = "\n".join([f"cell = {cell}", *(r.replace("o", ".").replace("x", "#") for r in rows)])
    return parse_maze_text(text + "\n", str(path), name=Path(path).stem)


ROWS = "1.2\nxxxxx\nxo>ox\nxxxxx\n"


def test_an_own_maze_format_is_read_wherever_a_maze_is_named(own, tmp_path):
    path = tmp_path / "corridor.rows"
    path.write_text(ROWS)
    with pytest.raises(
        MbnInputError, match=r"cannot tell the maze format from the suffix '\.rows'"
    ):
        load_maze(path)
    register_format(".rows", read_rows)
    assert maze_suffixes()[-1] == ".rows"
    maze = load_maze(str(path))
    assert maze.name == "corridor" and len(maze.starts) == 1
    assert np.asarray(maze.grid).shape == (3, 5)
    assert load_mazes(str(path))[0][0].name == "corridor"
    register_format(".rows", read_rows)  # the same again: a module imported twice
    # the maze a reader gives is checked as mbn's formats' are
    register_format(".solid", lambda p: Maze("solid", walls=[[0, 4, 0, 4]], bounds=(0, 4, 0, 4)))
    (tmp_path / "w.solid").write_text("")
    _refused(lambda: load_maze(tmp_path / "w.solid"), r"w\.solid: the maze has no free space")


def test_a_bad_format_is_refused_in_one_line(own, tmp_path):
    _refused(
        lambda: register_format("rows", read_rows),
        r"register_format\('rows'\): a suffix is a dot and a word",
    )
    _refused(
        lambda: register_format(".maze", read_rows),
        r"register_format\('\.maze'\): another reader has that suffix already",
    )
    _refused(
        lambda: register_format(".rows", "read_rows"),
        r"register_format\('\.rows'\): the reader must be a function",
    )
    register_format(".nothing", lambda path: None)
    (tmp_path / "a.nothing").write_text("")
    _refused(
        lambda: load_maze(tmp_path / "a.nothing"),
        r"a\.nothing: the reader of \.nothing files gave a NoneType, not a Maze",
    )
