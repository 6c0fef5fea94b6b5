"""The loader: built-in names and files by their suffix."""

from __future__ import annotations

from pathlib import Path

import pytest

from mbn.errors import MbnInputError
from mbn.world.mazes.builtin import BUILTIN_NAMES
from mbn.world.mazes.load import load_maze
from mbn.world.mazes.toml_maze import read_toml_maze


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_load_maze_dispatches_on_name_and_suffix(tmp_path: Path):
    assert load_maze("cross_LR").name == "cross_LR"
    grid = load_maze(write(tmp_path, "g.maze", ">.\n"))
    assert grid.name == "g" and grid.grid is not None
    text = "name = 'posts'\n[[wall]]\nxmin = 0\nxmax = 1\nymin = 0\nymax = 1\n"
    toml = load_maze(str(write(tmp_path, "w.toml", text)))
    assert toml.name == "posts" and not toml.outside_is_wall
    assert read_toml_maze(tmp_path / "w.toml").name == "posts"


def test_load_maze_errors(tmp_path: Path):
    with pytest.raises(MbnInputError) as info:
        load_maze("no_such_maze")
    msg = str(info.value)
    assert msg.startswith("unknown maze 'no_such_maze': neither a built-in (")
    for name in BUILTIN_NAMES:
        assert name in msg
    with pytest.raises(MbnInputError, match=r"missing\.maze: no such file$"):
        load_maze(tmp_path / "missing.maze")
    with pytest.raises(MbnInputError, match=r"cannot tell the maze format from the suffix '\.txt'"):
        load_maze(write(tmp_path, "m.txt", ">.\n"))
    folder = tmp_path / "d.maze"
    folder.mkdir()
    with pytest.raises(MbnInputError, match="is a folder"):
        load_maze(folder)
    bad = tmp_path / "b.maze"
    bad.write_bytes(b"\xff\xfe.\n")
    with pytest.raises(MbnInputError, match=r"b\.maze: not UTF-8 text"):
        load_maze(bad)
