"""Maze families (``mbn.world.mazes.families``): a seeded generator whose every maze is checked,
three disjoint splits of its seeds, names that load a generated maze or a split, and the test
split kept out of training and validation."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mbn.cli.main import main
from mbn.errors import MbnInputError
from mbn.world.junctions import decision_cells, free_neighbours, rule_route
from mbn.world.mazes import families as fm
from mbn.world.mazes.grid_text import parse_maze_text
from mbn.world.mazes.load import load_maze, load_mazes

#: Validation seeds the checks below draw (the test split is only ever a test).
SAMPLE = range(1_000_000, 1_000_008)

#: The families every run of the suite checks; the others (tiles4-6, turns2 and turns4-6, the
#: same generator with more tile kinds or other corner tiles) run with the slow tests.
IN_CI = ("grid", "tiles2", "tiles3", "turns3")


def _slow_but(names, in_ci=IN_CI):
    """``names`` as parameters, those outside ``in_ci`` marked slow."""
    return [n if n in in_ci else pytest.param(n, marks=pytest.mark.slow) for n in names]


EVERY_FAMILY = _slow_but(fm.FAMILIES)


@pytest.mark.parametrize("name", _slow_but(fm.FAMILIES, ("grid", "tiles3")))
def test_the_same_seed_gives_the_same_maze_and_others_differ(name):
    a = fm.generate_text(name, 12)
    fm._generate.cache_clear()  # made again from scratch, not read from the cache
    assert fm.generate_text(name, 12) == a
    assert fm.generate_text(name, 13) != a
    others = [fm.generate_text(o, 12) for o in fm.FAMILIES if o != name]
    assert all(_grid_of(o) != _grid_of(a) for o in others)


def _grid_of(text: str) -> str:
    return "\n".join(line for line in text.splitlines() if line and line[0] in "#.")


@pytest.mark.parametrize("name", EVERY_FAMILY)
def test_every_maze_has_the_familys_structure_and_judgeable_starts(name):
    """Corners, T junctions, plus crossings, dead ends, loops, a junction within 2 cells of a
    corner; one-cell corridors, connected; every start judgeable under every rule in use."""
    fam = fm.family(name)
    for seed in SAMPLE:
        maze = fm.generate(name, seed)
        assert fm.check(maze, fam) == [], (name, seed)
        info = fm.describe(maze)
        assert info["corners"] and info["t_junctions"] and info["plus_crossings"]
        assert info["dead_ends"] >= 1 and info["loops"] >= 1
        assert info["starts"] == fam.starts
        free = np.asarray(maze.grid) != "#"
        assert not np.any(free[1:, 1:] & free[:-1, 1:] & free[1:, :-1] & free[:-1, :-1])
        for start in maze.starts:
            for rule in fam.rules:
                assert rule_route(maze, tuple(start), rule, fam.junctions) is not None
        # start marks lie on straight corridor cells, facing along them
        nb = free_neighbours(maze)
        decision = decision_cells(maze)
        for x, y, theta in maze.starts:
            r = maze.grid.shape[0] - 1 - int(y // maze.cell)
            c = int(x // maze.cell)
            assert not decision[r, c] and nb[r, c].sum() == 2
            h = (1 - round(theta / (np.pi / 2))) % 4
            assert nb[r, c, h]


@pytest.mark.parametrize("name", _slow_but(("tiles2", "tiles3", "tiles4", "tiles5", "tiles6")))
def test_tiles_lie_at_every_distance_before_a_junction_and_mid_corridor(name):
    fam = fm.family(name)
    for seed in SAMPLE:
        maze = fm.generate(name, seed)
        places = fm.tile_places(maze)
        assert {p["colors"] for p in places} == set(fam.tile_kinds)
        for kind in fam.tile_kinds:
            mine = [p for p in places if p["colors"] == kind]
            for d in range(fam.reach + 1):
                assert any(d in p["before"] for p in mine), (seed, kind, d)
            assert any(p["mid"] for p in mine), (seed, kind)
        # every start drives over a tile and then through the judged junctions, from each
        # first rule, following the tiles
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


@pytest.mark.parametrize("name", EVERY_FAMILY)
def test_the_written_text_reads_back_as_the_same_maze(name):
    maze = fm.generate(name, 5)
    again = parse_maze_text(fm.generate_text(name, 5), "x.maze")
    np.testing.assert_array_equal(again.grid, maze.grid)
    np.testing.assert_array_equal(again.starts, maze.starts)
    assert again.tiles == maze.tiles and again.name == f"{name}:5"


def test_the_splits_are_disjoint_and_the_test_split_holds_100_mazes():
    ranges = list(fm.SPLITS.values())
    for i, a in enumerate(ranges):
        for b in ranges[i + 1 :]:
            assert a.stop <= b.start or b.stop <= a.start
    assert len(fm.split_seeds("test")) == fm.TEST_SIZE >= 100
    assert fm.split_of(0) == "train" and fm.split_of(1_000_000) == "validation"
    assert fm.split_of(2_000_099) == "test"


def test_a_test_seed_is_refused_for_training_and_validation():
    fm.check_use([3, 1_000_001], "validation")
    fm.check_use([2_000_000], "test")
    with pytest.raises(
        MbnInputError,
        match=r"^lf: maze seed 2000004 is in the test split, and "
        r"train may not use it \(a test maze is only ever a test\)$",
    ):
        fm.check_use([1, 2_000_004], "train", where="lf")
    with pytest.raises(MbnInputError, match="test split, and validation may not use it"):
        fm.check_use([2_000_000], "validation")
    with pytest.raises(MbnInputError, match="validation split, and train may not use it"):
        fm.check_use([1_000_000], "train")
    with pytest.raises(MbnInputError, match="in no split"):
        fm.check_use([5_000_000], "test")


def test_a_test_maze_looked_into_moves_to_validation_and_a_fresh_seed_takes_its_place():
    before, after = fm.SPLITS, fm.family_splits("tiles3")
    looked = fm.LOOKED_INTO["tiles3"]
    assert looked == (2_000_078,)
    # the test split: the same size, the looked-into seed out, the next fresh seed in
    assert len(after["test"]) == len(set(after["test"])) == fm.TEST_SIZE
    assert set(after["test"]) == (set(before["test"]) - set(looked)) | {2_000_100}
    # validation: its first members as before (what the stages read), the moved maze at the end
    assert list(after["validation"]) == [*before["validation"], *looked]
    assert set(after["test"]).isdisjoint(after["validation"])
    assert fm.split_of(2_000_078, "tiles3") == "validation"
    assert fm.split_of(2_000_100, "tiles3") == "test"
    fm.check_use([2_000_078], "validation", fam="tiles3")
    with pytest.raises(MbnInputError, match="2000078 is in the validation split, and test may"):
        fm.check_use([2_000_078], "test", fam="tiles3")
    with pytest.raises(MbnInputError, match=r"in no split \(.*test 2000000-2000077, 2000079-"):
        fm.split_of(2_000_101, "tiles3")
    # another family's maze of the same seed is another maze, never looked into
    assert fm.split_of(2_000_078, "tiles2") == "test" and fm.family_splits("tiles2") is fm.SPLITS
    names = fm.parse_name("tiles3/test")
    assert names.text == "tiles3/test" and names.seeds == tuple(after["test"])
    part = fm.parse_name("tiles3/test:77-79")
    assert part.seeds == (2_000_077, 2_000_079, 2_000_080) and part.text == "tiles3/test:77-79"


def test_names_load_a_generated_maze_or_a_split():
    maze = load_maze("tiles2:1000003")
    assert maze.name == "tiles2:1000003" and maze.grid is fm.generate("tiles2", 1_000_003).grid
    mazes, split = load_mazes("grid/validation:2-4")
    assert split == "grid/validation:2-4"
    assert [m.name for m in mazes] == [f"grid:{s}" for s in (1_000_002, 1_000_003, 1_000_004)]
    assert fm.parse_name("grid/test").text == "grid/test"
    assert len(fm.parse_name("grid/test").seeds) == fm.TEST_SIZE
    assert fm.parse_name("fig4") is None and fm.parse_name("runs/a.maze") is None


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        (
            "nope:3",
            r"unknown maze family 'nope' \(known: grid, tiles2, tiles3, tiles4, tiles5, tiles6, "
            r"turns2, turns3, turns4, turns5, turns6\)",
        ),
        ("grid:3000000", "maze seed 3000000 is in no split"),
        ("grid/test:0-100", r"split 'test': members 0-100 out of range \(0-99\)"),
        ("grid/train", r"the train split is open-ended: name a range \(train:0-99\)"),
        ("grid/other", "unknown split 'other'"),
        ("grid/test", r"'grid/test' names 100 mazes; one maze is needed here"),
        ("grid-3", "unknown maze 'grid-3': neither a built-in"),
    ],
)
def test_bad_names_are_one_line(spec, message):
    with pytest.raises(MbnInputError, match=message):
        load_maze(spec)


def test_parameters_that_cannot_make_a_maze_are_refused_in_one_line():
    with pytest.raises(MbnInputError, match=r"gap must be two integers low <= high"):
        fm.family("grid").replace(gap=(4, 2))
    with pytest.raises(MbnInputError, match=r"unknown parameter 'holes'"):
        fm.family("grid").replace(holes=3)
    with pytest.raises(MbnInputError, match="tile_rules must name a rule for every tile kind"):
        fm.family("tiles2").replace(tile_kinds=(1, 2, 3))
    tiny = fm.family("grid").replace(name="tiny", size=(5, 5))
    with pytest.raises(
        MbnInputError,
        match=r"^maze family 'tiny': no valid maze for seed 7 in "
        r"200 attempts \(the last: .*\); the parameters cannot produce one$",
    ):
        fm.generate(tiny, 7)


def test_mbn_mazes_generate_writes_a_maze_file(tmp_path, capsys):
    out = tmp_path / "t.maze"
    assert main(["mazes", "generate", "tiles3", "--seed", "9", "--out", str(out)]) == 0
    assert out.read_text() == fm.generate_text("tiles3", 9)
    assert "tiles3:9 (train split)" in capsys.readouterr().out
    assert load_maze(str(out)).tiles == fm.generate("tiles3", 9).tiles
    big = tmp_path / "big.maze"
    assert (
        main(["mazes", "generate", "grid", "--seed", "9", "--set", "size=25,31", "--out", str(big)])
        == 0
    )
    assert load_maze(str(big)).grid.shape[0] > fm.generate("grid", 9).grid.shape[0] - 1
    assert big.read_text().startswith("; --set size=25,31\n")
    for argv, message in (
        (["mazes", "generate", "maze", "--seed", "1"], "unknown maze family 'maze'"),
        (["mazes", "generate", "grid", "--seed", "1", "--set", "holes=2"], "unknown parameter"),
        (["mazes", "generate", "grid", "--seed", "1", "--set", "size=5,5"], "no valid maze"),
    ):
        bad = tmp_path / "bad.maze"
        assert main([*argv, "--out", str(bad)]) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1
        assert not bad.exists()


def test_mbn_mazes_families_lists_the_families_and_splits(capsys):
    assert main(["mazes", "families", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data["families"]) == set(fm.FAMILIES)
    assert data["splits"]["test"] == [2_000_000, 2_000_000 + fm.TEST_SIZE - 1]
    assert data["looked_into"] == {"tiles3": [2_000_078]}
    assert main(["mazes", "families"]) == 0
    assert "looked into, moved from tiles3's test split to its validation: 2000078" in (
        capsys.readouterr().out
    )


def test_the_zero_shot_suite_holds_ten_mazes_judgeable_under_their_familys_rules():
    names = {n for suite in fm.ZERO_SHOT.values() for n in suite}
    assert len(names) >= 10
    for name, suite in fm.ZERO_SHOT.items():
        fam = fm.family(name)
        mazes, split = load_mazes(f"{name}/zero-shot")
        assert split == f"{name}/zero-shot" and [m.name for m in mazes] == list(suite)
        for maze in mazes:
            assert len(maze.starts) >= 8, maze.name
            for start in maze.starts:
                for rule in fam.rules:
                    assert rule_route(maze, tuple(start), rule, fam.junctions) is not None
                for first in fam.first_rules:
                    assert (
                        rule_route(
                            maze,
                            tuple(start),
                            first,
                            fam.junctions,
                            follow_tiles=True,
                            count_from_tile=True,
                            tile_rules=fam.tile_rules,
                        )
                        is not None
                    ), (maze.name, tuple(start), first)


def test_the_zero_shot_files_are_what_the_script_makes():
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[3]
    proc = subprocess.run(
        [
            sys.executable,
            str(root / "scripts" / "make_zero_shot.py"),
            "--check",
            "--out",
            str(root / "src" / "mbn" / "data" / "mazes"),
        ],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr


def test_a_settings_file_that_validates_on_a_test_maze_is_refused(tmp_path, capsys):
    """``[validation] maze`` naming a generated maze of a test split: one line naming the file,
    line and setting, exit 2, nothing written."""
    bad = tmp_path / "bad.toml"
    bad.write_text('[validation]\nmaze = "tiles2:2000005"\n')
    out = tmp_path / "run"
    assert main(["reproduce", "--quick", "--config", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith(
        "bad.toml:2: validation.maze: maze seed 2000005 is in the test split, and validation "
        "may not use it (a test maze is only ever a test)"
    )
    assert len(err.splitlines()) == 1 and not out.exists()
