"""The maze loader: a built-in name or a ``.maze``, ``.toml`` or Player/Stage ``.world`` file.

This is the one module that knows every reader and picks one:

* a built-in name (:data:`mbn.world.mazes.builtin.BUILTIN_NAMES`): :mod:`~mbn.world.mazes.builtin`;
* a generated maze's name, ``FAMILY:SEED`` (``grid:2000003``): :mod:`~mbn.world.mazes.families`
  (:func:`load_mazes` also takes a split, ``FAMILY/SPLIT`` or ``FAMILY/SPLIT:A-B``);
* ``.maze``: the text grid of :mod:`~mbn.world.mazes.grid_text`;
* ``.toml``: the rectangles of :mod:`~mbn.world.mazes.toml_maze`;
* ``.world``: the Player/Stage world files of :mod:`~mbn.world.mazes.stage`.

Every maze it returns has passed :func:`~mbn.world.mazes.validate.validate_maze`.
"""

from __future__ import annotations

import os
from pathlib import Path

from mbn.errors import MbnInputError
from mbn.world.mazes.builtin import BUILTIN_NAMES, builtin_maze
from mbn.world.mazes.grid_text import grid_shape, read_maze_file
from mbn.world.mazes.model import Maze
from mbn.world.mazes.stage import read_stage_world
from mbn.world.mazes.toml_maze import read_toml_maze

__all__ = ["MAZE_SUFFIXES", "load_maze", "load_mazes", "maze_file_grid_shape"]

#: File suffixes :func:`load_maze` reads.
MAZE_SUFFIXES = (".maze", ".toml", ".world")


def load_maze(spec: str | os.PathLike[str]) -> Maze:
    """A maze by built-in name (:data:`mbn.world.mazes.builtin.BUILTIN_NAMES`) or from a ``.maze``,
    ``.toml`` or Player/Stage ``.world`` file.

    A string that is a built-in name is that built-in; one of the form ``FAMILY:SEED`` a
    generated maze (:mod:`mbn.world.mazes.families`); anything else is a path.
    """
    if isinstance(spec, str) and spec in BUILTIN_NAMES:
        return builtin_maze(spec)
    if isinstance(spec, str) and not Path(spec).exists():
        from mbn.world.mazes import families

        name = families.parse_name(spec)
        if name is not None:
            if name.split is not None:
                count = len(name.seeds) or len(name.builtins)
                raise MbnInputError(
                    f"{spec!r} names {count} mazes; one maze is needed here: a generated one, "
                    f"{name.family}:SEED, or a built-in by name"
                )
            return families.generate(name.family, name.seeds[0])
    path = Path(spec)
    suffix = path.suffix.lower()
    if not path.exists():
        if suffix in MAZE_SUFFIXES:
            raise MbnInputError(f"{path}: no such file")
        raise MbnInputError(
            f"unknown maze {str(spec)!r}: neither a built-in ({', '.join(BUILTIN_NAMES)}), a "
            f"generated maze (FAMILY:SEED) nor an existing {'/'.join(MAZE_SUFFIXES)} file"
        )
    if suffix == ".maze":
        return read_maze_file(path)
    if suffix == ".toml":
        return read_toml_maze(path)
    if suffix == ".world":
        return read_stage_world(path)
    raise MbnInputError(
        f"{path}: cannot tell the maze format from the suffix {path.suffix!r}"
        f" (expected {', '.join(MAZE_SUFFIXES)})"
    )


def load_mazes(spec: str | os.PathLike[str]) -> tuple[list[Maze], str | None]:
    """The mazes ``spec`` names and the split they are (None for one maze): a split of a
    family (``grid/test``, ``tiles2/validation:0-9``), or anything :func:`load_maze` takes."""
    if isinstance(spec, str) and not Path(spec).exists():
        from mbn.world.mazes import families

        name = families.parse_name(spec)
        if name is not None and name.split == "zero-shot":
            return [builtin_maze(n) for n in name.builtins], name.text
        if name is not None and name.split is not None:
            return [families.generate(name.family, s) for s in name.seeds], name.text
    return [load_maze(spec)], None


def maze_file_grid_shape(spec: str | os.PathLike[str]) -> tuple[int, int] | None:
    """The ``(rows, columns)`` of the ``.maze`` file ``spec`` names, from its lines alone (a
    quick look before reading it, e.g. to refuse a grid too large to draw); None for a built-in
    name or a file of another format."""
    path = Path(spec)
    if str(spec) in BUILTIN_NAMES or path.suffix.lower() != ".maze" or not path.is_file():
        return None
    return grid_shape(path)
