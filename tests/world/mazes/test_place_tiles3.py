"""scripts/place_tiles3.py places the shipped tiles3 again from its seed (the maze's record of
how it was made holds), and its placements meet the three-tile mazes' test."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from mbn.world.junctions import program_swaps_caught
from mbn.world.mazes.load import load_maze

SCRIPT = Path(__file__).resolve().parents[3] / "scripts" / "place_tiles3.py"


def _script():
    spec = importlib.util.spec_from_file_location("place_tiles3", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_the_script_places_tiles3_as_shipped(capsys: pytest.CaptureFixture[str]):
    assert _script().main(["tiles3", "--seed", "0"]) == 0
    printed = capsys.readouterr()
    rows = printed.out.strip().splitlines()
    assert np.array_equal(np.array([list(r) for r in rows]), load_maze("tiles3").grid)
    assert "placement after" in printed.err


def test_the_shipped_mazes_meet_the_scripts_conditions():
    place = _script()
    for name in ("tiles3", "tiles3_heldout", "tiles3_validation"):
        maze = load_maze(name)
        assert place.score(maze, 4) == 4 * 6 * 2, name
        counts = program_swaps_caught(maze, "right", 3, place.TILE_RULES)
        assert min(counts.values()) >= 4, (name, counts)


def test_a_search_that_cannot_succeed_says_so(capsys: pytest.CaptureFixture[str]):
    assert _script().main(["tiles3", "--seed", "0", "--caught", "11", "--steps", "3"]) == 1
    assert "no placement in 3 moves" in capsys.readouterr().err
