"""TOML mazes (``.toml``, read with :mod:`tomllib`); lengths in metres, **angles in degrees**::


    name = "corridor"
    [[free]]                      # free rectangles: all else inside their bounding box is wall
    xmin = 0.0
    xmax = 6.0
    ymin = 0.0
    ymax = 1.2
    [[wall]]                      # solid rectangles (may be combined with [[free]])
    xmin = 2.0
    xmax = 2.4
    ymin = 0.0
    ymax = 0.3
    [[tile]]
    x = 4.0
    y = 0.6
    colors = 2                    # 1 to 6; optional: width (1.2), length (0.3), heading (90)
    [[start]]
    x = 0.6
    y = 0.6
    theta = 0                     # degrees, counter-clockwise from east

With ``[[free]]`` tables the outside of their bounding box is wall and ``bounds`` is that box; the
solid complement of the free rectangles is computed exactly (the grid of their distinct edge
coordinates, merged into rectangles). With ``[[wall]]`` tables only, the outside is open and
``bounds`` is the walls' bounding box (grown, if need be, to hold every start and tile centre).

Every maze read here passes :func:`~mbn.world.mazes.validate.validate_maze`.
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from mbn.config import toml_error
from mbn.errors import MbnInputError
from mbn.io import expect_number
from mbn.world.mazes.model import (
    DEFAULT_CELL,
    DEFAULT_TILE_LENGTH,
    TILE_COLORS,
    Maze,
    Tile,
    merge_grid,
)
from mbn.world.mazes.validate import read_text, validate_maze

__all__ = ["parse_toml_maze", "read_toml_maze"]

_RECT_KEYS = ("xmin", "xmax", "ymin", "ymax")
_TABLE_KEYS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    # table: (required keys, optional keys)
    "wall": (_RECT_KEYS, ()),
    "free": (_RECT_KEYS, ()),
    "tile": (("x", "y", "colors"), ("width", "length", "heading")),
    "start": (("x", "y", "theta"), ()),
}


def _table_lines(text: str, table: str) -> list[int]:
    """1-based line numbers of the ``[[table]]`` headers of ``text``, in order."""
    pattern = re.compile(r"^\s*\[\[\s*" + re.escape(table) + r"\s*\]\]\s*(#.*)?$")
    return [n for n, line in enumerate(text.splitlines(), start=1) if pattern.match(line)]


def parse_toml_maze(
    text: str,
    where: str = "<toml>",
    *,
    name: str | None = None,
    source: str = "",
) -> Maze:
    """Parse a TOML maze (see the module docstring) into a validated :class:`Maze`.

    Errors in a table name it and its index, with the line of its ``[[...]]`` header when the
    table is written that way, e.g. ``maze.toml:12: [[wall]] #3: xmin must be < xmax``.
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise toml_error(exc, text, where) from None
    except ValueError as exc:  # an integer of thousands of digits
        raise MbnInputError(f"{where}: invalid TOML ({str(exc).split(':')[0]})") from None

    for key in data:
        if key not in (*_TABLE_KEYS, "name"):
            raise MbnInputError(
                f"{where}: unknown top-level key {key!r} (expected name, [[wall]], [[free]],"
                " [[tile]], [[start]])"
            )

    tables: dict[str, list[tuple[str, dict[str, float]]]] = {}
    for table, (required, optional) in _TABLE_KEYS.items():
        entries = data.get(table, [])
        if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
            raise MbnInputError(f"{where}: {table} must be an array of tables ([[{table}]])")
        lines = _table_lines(text, table)
        parsed: list[tuple[str, dict[str, float]]] = []
        for k, entry in enumerate(entries):
            line = f":{lines[k]}" if len(lines) == len(entries) else ""
            label = f"{where}{line}: [[{table}]] #{k + 1}"
            for key in entry:
                if key not in required and key not in optional:
                    allowed = " ".join(required + optional)
                    raise MbnInputError(f"{label}: unknown key {key!r} (expected {allowed})")
            for key in required:
                if key not in entry:
                    raise MbnInputError(f"{label}: missing {key}")
            values = {key: _number_in(entry[key], label, key) for key in entry}
            parsed.append((label, values))
        tables[table] = parsed

    name_value = data.get("name", name if name is not None else Path(where).stem)
    if not isinstance(name_value, str) or not name_value:
        raise MbnInputError(f"{where}: name must be a non-empty string, got {name_value!r}")

    rect_arrays: dict[str, np.ndarray] = {}
    for table in ("wall", "free"):
        rects = []
        for label, v in tables[table]:
            if not v["xmin"] < v["xmax"]:
                raise MbnInputError(
                    f"{label}: xmin must be < xmax, got {v['xmin']:g}, {v['xmax']:g}"
                )
            if not v["ymin"] < v["ymax"]:
                raise MbnInputError(
                    f"{label}: ymin must be < ymax, got {v['ymin']:g}, {v['ymax']:g}"
                )
            rects.append([v[k] for k in _RECT_KEYS])
        rect_arrays[table] = np.array(rects, dtype=np.float64).reshape(-1, 4)

    tiles: list[Tile] = []
    for label, v in tables["tile"]:
        colors = v["colors"]
        if colors not in TILE_COLORS:
            raise MbnInputError(
                f"{label}: colors must be an integer from {TILE_COLORS[0]} to "
                f"{TILE_COLORS[-1]}, got {colors:g}"
            )
        width = v.get("width", DEFAULT_CELL)
        length = v.get("length", DEFAULT_TILE_LENGTH)
        if width <= 0 or length <= 0:
            raise MbnInputError(f"{label}: width and length must be > 0, got {width:g}, {length:g}")
        tiles.append(
            Tile(
                x=v["x"],
                y=v["y"],
                colors=int(colors),
                width=width,
                length=length,
                heading=math.radians(v.get("heading", 90.0)),
            )
        )
    starts = np.array(
        [[v["x"], v["y"], math.radians(v["theta"])] for _, v in tables["start"]], dtype=np.float64
    ).reshape(-1, 3)

    walls, free = rect_arrays["wall"], rect_arrays["free"]
    if walls.shape[0] == 0 and free.shape[0] == 0:
        raise MbnInputError(f"{where}: a TOML maze needs at least one [[wall]] or [[free]] table")
    if free.shape[0]:
        bounds = (
            float(free[:, 0].min()),
            float(free[:, 1].max()),
            float(free[:, 2].min()),
            float(free[:, 3].max()),
        )
        solid = _complement(free)
        all_walls = np.concatenate([solid, walls], axis=0)
        outside_is_wall = True
    else:
        xs = [walls[:, 0].min(), walls[:, 1].max()]
        ys = [walls[:, 2].min(), walls[:, 3].max()]
        for t in tiles:
            xs += [t.x]
            ys += [t.y]
        xs += list(starts[:, 0])
        ys += list(starts[:, 1])
        bounds = (float(min(xs)), float(max(xs)), float(min(ys)), float(max(ys)))
        all_walls = walls
        outside_is_wall = False

    maze = Maze(
        name=name_value,
        walls=all_walls,
        bounds=bounds,
        outside_is_wall=outside_is_wall,
        tiles=tuple(tiles),
        starts=starts,
        source=source or where,
    )
    validate_maze(
        maze,
        where,
        start_labels=[label for label, _ in tables["start"]],
        tile_labels=[label for label, _ in tables["tile"]],
    )
    return maze


def _number_in(value: Any, label: str, key: str) -> float:
    return expect_number(value, f"{label}: {key}")


def _complement(free: np.ndarray) -> np.ndarray:
    """The solid part of the bounding box of the ``free`` rectangles, as rectangles (exact)."""
    xs = np.unique(np.concatenate([free[:, 0], free[:, 1]]))
    ys = np.unique(np.concatenate([free[:, 2], free[:, 3]]))
    cx = (xs[:-1] + xs[1:]) / 2
    cy = (ys[:-1] + ys[1:]) / 2
    inx = (free[:, 0][None, :] < cx[:, None]) & (cx[:, None] < free[:, 1][None, :])  # (X, K)
    iny = (free[:, 2][None, :] < cy[:, None]) & (cy[:, None] < free[:, 3][None, :])  # (Y, K)
    is_free = (iny.astype(np.int32) @ inx.T.astype(np.int32)) > 0  # (Y, X), row 0 south
    solid = ~is_free[::-1, :]  # first row north
    return merge_grid(solid, xs, ys)


def read_toml_maze(path: str | os.PathLike[str]) -> Maze:
    """Read a TOML maze file (see the module docstring)."""
    text = read_text(path)
    return parse_toml_maze(text, str(path), name=Path(path).stem, source=str(path))
