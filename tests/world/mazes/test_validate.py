"""The checks every maze passes, and reading a maze file's text."""

from __future__ import annotations

from pathlib import Path

import pytest

from mbn.errors import MbnInputError
from mbn.world.mazes.model import Maze
from mbn.world.mazes.validate import read_text, validate_maze


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_validate_maze_rejects_a_maze_without_free_space():
    full = Maze(name="full", walls=[[0, 1, 0, 2], [1, 2, 0, 2]], bounds=(0, 2, 0, 2))
    with pytest.raises(MbnInputError, match=r"^full: the maze has no free space$"):
        validate_maze(full, "full")
    open_outside = Maze(name="o", walls=[[0, 2, 0, 2]], bounds=(0, 2, 0, 2), outside_is_wall=False)
    validate_maze(open_outside, "o")  # the outside is free


def test_read_text_errors_name_the_file(tmp_path: Path):
    with pytest.raises(MbnInputError, match=r"missing\.maze: no such file$"):
        read_text(tmp_path / "missing.maze")
    folder = tmp_path / "d.maze"
    folder.mkdir()
    with pytest.raises(MbnInputError, match="is a folder"):
        read_text(folder)
    bad = tmp_path / "b.maze"
    bad.write_bytes(b"\xff\xfe.\n")
    with pytest.raises(MbnInputError, match=r"b\.maze: not UTF-8 text"):
        read_text(bad)
    assert read_text(write(tmp_path, "ok.maze", ">.\n")) == ">.\n"
