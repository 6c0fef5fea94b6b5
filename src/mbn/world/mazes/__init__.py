"""Mazes: the data, its checks, the file readers, the built-ins and generated mazes.

* :mod:`~mbn.world.mazes.model` — :class:`Maze` and :class:`Tile`, the data every other part reads;
* :mod:`~mbn.world.mazes.validate` — the checks every maze passes, reading a file's text;
* :mod:`~mbn.world.mazes.grid_text` — the ``.maze`` text grid;
* :mod:`~mbn.world.mazes.toml_maze` — TOML rectangles;
* :mod:`~mbn.world.mazes.stage` — Player/Stage ``.world`` files;
* :mod:`~mbn.world.mazes.builtin` — the built-in mazes;
* :mod:`~mbn.world.mazes.generate` — generated corridor mazes;
* :mod:`~mbn.world.mazes.families` — maze families: a checked generator and the splits of its
  seeds;
* :mod:`~mbn.world.mazes.load` — :func:`load_maze`: a built-in name, a generated maze or a file,
  by its suffix.

``Maze`` and ``load_maze`` are importable from here; their modules are imported on first use, so
importing this package (as every submodule import does) costs nothing.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from mbn.world.mazes.load import load_maze
    from mbn.world.mazes.model import Maze

__all__ = ["Maze", "load_maze"]

_HOMES = {"Maze": "mbn.world.mazes.model", "load_maze": "mbn.world.mazes.load"}


def __getattr__(name: str) -> Any:
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
