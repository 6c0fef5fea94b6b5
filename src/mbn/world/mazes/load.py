"""The maze loader: a built-in name or a ``.maze``, ``.toml`` or Player/Stage ``.world`` file.

This is the one module that knows every reader and picks one:

* a built-in name (:data:`mbn.world.mazes.builtin.BUILTIN_NAMES`): :mod:`~mbn.world.mazes.builtin`;
* a generated maze's name, ``FAMILY:SEED`` (``grid:2000003``): :mod:`~mbn.world.mazes.families`
  (:func:`load_mazes` also takes a split, ``FAMILY/SPLIT`` or ``FAMILY/SPLIT:A-B``);
* ``.maze``: the text grid of :mod:`~mbn.world.mazes.grid_text`;
* ``.toml``: the rectangles of :mod:`~mbn.world.mazes.toml_maze`;
* ``.world``: the Player/Stage world files of :mod:`~mbn.world.mazes.stage`;
* a suffix of your own: the reader registered for it (:func:`register_format`).

Every maze it returns has passed :func:`~mbn.world.mazes.validate.validate_maze`.

**A format of your own** is one function, the path to the :class:`~mbn.world.mazes.model.Maze`
(for a grid, :func:`~mbn.world.mazes.grid_text.parse_maze_text` of the text it builds), and a
registration by suffix, from outside ``mbn``; the formats above are registered the same way::

    register_format(".txt", read_my_maze)

After it, a file of that suffix is a maze wherever one is named (settings, ``mbn evaluate
--maze``, ``mbn show-maze``), checked by :func:`~mbn.world.mazes.validate.validate_maze`.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from mbn.errors import MbnInputError
from mbn.world.mazes.builtin import BUILTIN_NAMES, builtin_maze
from mbn.world.mazes.grid_text import grid_shape, read_maze_file
from mbn.world.mazes.model import Maze
from mbn.world.mazes.stage import read_stage_world
from mbn.world.mazes.toml_maze import read_toml_maze
from mbn.world.mazes.validate import validate_maze

__all__ = [
    "MAZE_SUFFIXES",
    "load_maze",
    "load_mazes",
    "maze_file_grid_shape",
    "maze_suffixes",
    "register_format",
]

#: File suffixes of mbn's own formats (:func:`maze_suffixes`: with the registered ones).
MAZE_SUFFIXES = (".maze", ".toml", ".world")
_SUFFIX = re.compile(r"^\.[a-z0-9][a-z0-9_-]*$")


@dataclass(frozen=True)
class _Format:
    """A maze format: the reader of a file and whether it checks the maze itself."""

    reader: Callable[[Path], Maze]
    validates: bool


#: The formats by suffix (:func:`register_format`).
_FORMATS: dict[str, _Format] = {}


def register_format(
    suffix: str, reader: Callable[[Path], Maze], *, validates: bool = False
) -> None:
    """Register a maze format: a file whose suffix is ``suffix`` (``".txt"``; any case) is read
    by ``reader(path)``, which gives a :class:`~mbn.world.mazes.model.Maze` (or raises an
    :class:`~mbn.errors.MbnInputError` naming what is wrong in the file). The maze is then
    checked by :func:`~mbn.world.mazes.validate.validate_maze` unless ``validates`` (the reader
    checks it itself, as mbn's do). A suffix taken by another reader is refused in one line (the
    same reader again is allowed: a module imported twice)."""
    where = f"register_format({suffix!r})"
    if not isinstance(suffix, str) or not _SUFFIX.match(suffix.lower()):
        raise MbnInputError(f"{where}: a suffix is a dot and a word, e.g. '.txt'")
    if not callable(reader):
        raise MbnInputError(f"{where}: the reader must be a function of the file's path")
    key = suffix.lower()
    held = _FORMATS.get(key)
    if held is not None and held != _Format(reader, validates):
        raise MbnInputError(f"{where}: another reader has that suffix already")
    _FORMATS[key] = _Format(reader, validates)


def maze_suffixes() -> tuple[str, ...]:
    """The suffixes of the maze files :func:`load_maze` reads: mbn's, then the registered."""
    return tuple(_FORMATS)


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
        if suffix in _FORMATS:
            raise MbnInputError(f"{path}: no such file")
        raise MbnInputError(
            f"unknown maze {str(spec)!r}: neither a built-in ({', '.join(BUILTIN_NAMES)}), a "
            f"generated maze (FAMILY:SEED) nor an existing {'/'.join(_FORMATS)} file"
        )
    found = _FORMATS.get(suffix)
    if found is None:
        raise MbnInputError(
            f"{path}: cannot tell the maze format from the suffix {path.suffix!r}"
            f" (expected {', '.join(_FORMATS)})"
        )
    maze = found.reader(path)
    if found.validates:
        return maze
    if not isinstance(maze, Maze):
        raise MbnInputError(
            f"{path}: the reader of {suffix} files gave a {type(maze).__name__}, not a Maze"
        )
    validate_maze(maze, str(path))
    return maze


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


# mbn's formats: registered as a format of your own is (their readers check the maze)
register_format(".maze", read_maze_file, validates=True)
register_format(".toml", read_toml_maze, validates=True)
register_format(".world", read_stage_world, validates=True)
