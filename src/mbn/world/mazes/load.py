"""Reading mazes from files: the ``.maze`` text grid, TOML rectangles, and the loader.

``.maze`` (a grid of square cells, one character each)::

    ; a T junction: comments start with ';'
    cell = 1.2          ; optional header lines "key = value" before the grid: cell, name
    name = tee
    #######
    .......
    ###1###
    ###^###

* ``#`` wall, ``.`` free, ``1``/``2`` free with a one-/two-colour tile, ``>`` ``<`` ``^`` ``v``
  free with a start pose at the cell centre facing east, west, north, south.
* The first grid line is north. The grid's south-west corner is (0, 0): with ``R`` grid lines,
  the cell on line ``r`` (0 = top) and column ``c`` covers ``x`` in ``[c cell, (c + 1) cell]`` and
  ``y`` in ``[(R - 1 - r) cell, (R - r) cell]``. Outside the grid is wall.
* Lines whose first non-blank character is ``;`` are comments, anywhere in the file (also between
  grid lines); a header line may end in a ``; comment``. Trailing white space is ignored; lines
  shorter than the longest are padded with wall. Blank lines before the grid and after it are
  ignored; a blank line inside the grid (with grid lines after it) is an error, as is a header
  line after the grid has started.
* A tile lies across the corridor at its cell's centre, ``cell`` wide and
  :data:`~mbn.world.mazes.model.DEFAULT_TILE_LENGTH` long. Its heading (the corridor's direction) is
  east (0) when the cell has more free east/west neighbours than north/south ones, and north (pi/2)
  otherwise. So the heading is pi/2 in a north-south corridor and at a dead end open to the north or
  south; 0 in an east-west corridor; in a T junction it follows the T's bar (the side with two free
  neighbours); ties (a plus crossing, an L corner, an isolated cell) give pi/2.

TOML (``.toml``, read with :mod:`tomllib`); lengths in metres, **angles in degrees**::

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
    colors = 2                    # optional: width (1.2), length (0.3), heading (degrees, 90)
    [[start]]
    x = 0.6
    y = 0.6
    theta = 0                     # degrees, counter-clockwise from east

With ``[[free]]`` tables the outside of their bounding box is wall and ``bounds`` is that box; the
solid complement of the free rectangles is computed exactly (the grid of their distinct edge
coordinates, merged into rectangles). With ``[[wall]]`` tables only, the outside is open and
``bounds`` is the walls' bounding box (grown, if need be, to hold every start and tile centre).

Every maze read here passes :func:`validate_maze`. :func:`load_maze` also accepts the built-in
names of :mod:`mbn.world.mazes.builtin` and Player/Stage ``.world`` files
(:mod:`mbn.world.mazes.stage`).
"""

from __future__ import annotations

import functools
import math
import os
import re
import tomllib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mbn.errors import MbnInputError
from mbn.world.mazes.model import (
    DEFAULT_CELL,
    DEFAULT_TILE_LENGTH,
    Maze,
    Tile,
    merge_cells,
    merge_grid,
)

__all__ = [
    "GRID_CHARS",
    "MAZE_SUFFIXES",
    "START_HEADINGS",
    "grid_tile_heading",
    "load_maze",
    "parse_maze_text",
    "parse_toml_maze",
    "read_maze_file",
    "read_text",
    "read_toml_maze",
    "validate_maze",
]

#: The characters of a ``.maze`` grid, in the order error messages list them.
GRID_CHARS = ("#", ".", "1", "2", ">", "<", "^", "v")
#: Heading (radians) of the start pose each start mark stands for.
START_HEADINGS = {">": 0.0, "<": math.pi, "^": math.pi / 2, "v": -math.pi / 2}
#: File suffixes :func:`load_maze` reads.
MAZE_SUFFIXES = (".maze", ".toml", ".world")

_HEADER_RE = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*([^;]*?)\s*(;.*)?$")


# ---------------------------------------------------------------------------------------------
# shared helpers


def read_text(path: str | os.PathLike[str]) -> str:
    """The text of ``path`` (UTF-8), or an :class:`MbnInputError` naming it."""
    p = Path(path)
    if not p.exists():
        raise MbnInputError(f"{p}: no such file")
    if p.is_dir():
        raise MbnInputError(f"{p}: is a folder, not a file")
    try:
        return p.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise MbnInputError(f"{p}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise MbnInputError(f"{p}: cannot read ({exc.strerror})") from None


def _fmt_pose(pose: np.ndarray) -> str:
    return f"({pose[0]:g}, {pose[1]:g}, {math.degrees(pose[2]):g} deg)"


def _has_free_space(maze: Maze) -> bool:
    """Whether some point of a walled maze's bounds is not inside a wall (exact: the walls' edge
    coordinates cut the bounds into cells, each wholly free or wholly solid)."""
    if not maze.outside_is_wall:
        return True
    x0, x1, y0, y1 = maze.bounds
    w = maze.walls
    xs = np.unique(np.clip(np.concatenate([[x0, x1], w[:, 0], w[:, 1]]), x0, x1))
    ys = np.unique(np.clip(np.concatenate([[y0, y1], w[:, 2], w[:, 3]]), y0, y1))
    cx = (xs[:-1] + xs[1:]) / 2
    cy = (ys[:-1] + ys[1:]) / 2
    if cx.size == 0 or cy.size == 0:
        return False
    inx = (w[:, 0][None, :] < cx[:, None]) & (cx[:, None] < w[:, 1][None, :])  # (X, K)
    iny = (w[:, 2][None, :] < cy[:, None]) & (cy[:, None] < w[:, 3][None, :])  # (Y, K)
    # a cell (i, j) is solid if some wall k covers both its x and y centre
    covered = (inx.astype(np.int32) @ iny.T.astype(np.int32)) > 0  # (X, Y)
    return not bool(np.all(covered))


def _bucket(n: int) -> int:
    return max(8, 1 << max(0, n - 1).bit_length())


@functools.cache
def _jitted_collides() -> Callable[[Any, Any], Any]:
    import jax

    from mbn.world.geometry import collides

    return jax.jit(collides)


def _starts_collide(starts: np.ndarray, rects: np.ndarray) -> np.ndarray:
    """:func:`mbn.world.geometry.collides` of every start against ``rects``, as bools ``(S,)``.

    Starts and rectangles are padded to power-of-two counts (copies of the first start; unit
    squares far from everything) so that the jitted check compiles once per size class rather than
    once per maze.
    """
    n_s, n_r = len(starts), len(rects)
    far = 1e6 + float(np.max(np.abs(rects))) + float(np.max(np.abs(starts[:, :2])))
    pad_s = np.repeat(starts[:1], _bucket(n_s) - n_s, axis=0)
    pad_r = np.tile([[far, far + 1.0, far, far + 1.0]], (_bucket(n_r) - n_r, 1))
    hits = _jitted_collides()(np.concatenate([starts, pad_s]), np.concatenate([rects, pad_r]))
    return np.asarray(hits, dtype=bool).reshape(-1)[:n_s]


def validate_maze(
    maze: Maze,
    where: str,
    *,
    start_labels: Sequence[str] | None = None,
    tile_labels: Sequence[str] | None = None,
) -> None:
    """Check that ``maze`` is usable; raise a one-line :class:`MbnInputError` otherwise.

    * it has free space;
    * no start pose's robot body overlaps a wall (:func:`mbn.world.geometry.collides` against
      :meth:`Maze.solid_rects`), and in a walled maze every start lies inside ``bounds``;
    * every tile's centre is in free space.

    Args:
        maze: the maze.
        where: the prefix of messages (a file name, or ``"file:line"``).
        start_labels, tile_labels: optional full prefixes, one per start / tile, replacing
            ``"{where}: start #k"`` / ``"{where}: tile #k"`` (e.g. with the file line of each).
    """
    if not _has_free_space(maze):
        raise MbnInputError(f"{where}: the maze has no free space")

    def start_label(k: int) -> str:
        if start_labels is not None:
            return start_labels[k]
        return f"{where}: start #{k + 1}"

    def tile_label(k: int) -> str:
        if tile_labels is not None:
            return tile_labels[k]
        return f"{where}: tile #{k + 1}"

    starts = maze.starts
    if starts.shape[0]:
        if maze.outside_is_wall:
            x0, x1, y0, y1 = maze.bounds
            for k, s in enumerate(starts):
                if not (x0 <= s[0] <= x1 and y0 <= s[1] <= y1):
                    raise MbnInputError(
                        f"{start_label(k)} at {_fmt_pose(s)} lies outside the maze's bounds"
                        f" [{x0:g}, {x1:g}] x [{y0:g}, {y1:g}]"
                    )
        rects = maze.solid_rects()
        if rects.shape[0]:
            hits = _starts_collide(starts, rects)
            bad = np.flatnonzero(hits)
            if bad.size:
                first = int(bad[0])
                raise MbnInputError(
                    f"{start_label(first)} at {_fmt_pose(starts[first])}: the robot's body"
                    " overlaps a wall"
                )
    for k, tile in enumerate(maze.tiles):
        if not maze.is_free(tile.x, tile.y):
            raise MbnInputError(
                f"{tile_label(k)} at ({tile.x:g}, {tile.y:g}): its centre is not in free space"
            )


# ---------------------------------------------------------------------------------------------
# .maze text grids


def grid_tile_heading(grid: np.ndarray, row: int, col: int) -> float:
    """The heading of a tile in cell ``(row, col)`` of a grid: 0 (east-west corridor) when the cell
    has more free east/west neighbours than north/south ones, pi/2 otherwise (ties, junctions with
    free neighbours both ways counted equal, and isolated cells go north-south)."""
    rows, cols = grid.shape

    def free(r: int, c: int) -> bool:
        return 0 <= r < rows and 0 <= c < cols and grid[r, c] != "#"

    vertical = int(free(row - 1, col)) + int(free(row + 1, col))
    horizontal = int(free(row, col - 1)) + int(free(row, col + 1))
    return 0.0 if horizontal > vertical else math.pi / 2


def _parse_header_value(key: str, value: str, at: str) -> float | str:
    if key == "cell":
        try:
            cell = float(value)
        except ValueError:
            raise MbnInputError(f"{at}: cell must be a number of metres, got {value!r}") from None
        if not (math.isfinite(cell) and cell > 0):
            raise MbnInputError(f"{at}: cell must be a finite number > 0, got {value!r}")
        return cell
    if key == "name":
        if len(value) >= 2 and value[0] == value[-1] and value[0] in "\"'":
            value = value[1:-1]
        if not value:
            raise MbnInputError(f"{at}: name must not be empty")
        return value
    raise MbnInputError(f"{at}: unknown header key {key!r} (expected cell or name)")


def parse_maze_text(
    text: str,
    where: str = "<maze>",
    *,
    name: str | None = None,
    source: str = "",
) -> Maze:
    """Parse the ``.maze`` format (see the module docstring) into a validated :class:`Maze`.

    Args:
        text: the file's text.
        where: the file name used in error messages (``"{where}:{line}: ..."``).
        name: the maze's name when the text has no ``name`` header (default: ``where``'s stem).
        source: recorded as :attr:`Maze.source` (default: ``where``).
    """
    header: dict[str, float | str] = {}
    grid_lines: list[tuple[int, str]] = []  # (1-based line number, text)
    blank_after_grid: int | None = None
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.rstrip()
        stripped = line.lstrip()
        at = f"{where}:{number}"
        if stripped.startswith(";"):
            continue
        if not stripped:
            if grid_lines and blank_after_grid is None:
                blank_after_grid = number
            continue
        if "=" in line:
            if grid_lines:
                raise MbnInputError(f"{at}: header line after the grid has started: {stripped!r}")
            match = _HEADER_RE.match(line)
            if match is None:
                raise MbnInputError(f"{at}: bad header line {stripped!r} (expected key = value)")
            key, value = match.group(1), match.group(2)
            if key in header:
                raise MbnInputError(f"{at}: header key {key!r} given twice")
            header[key] = _parse_header_value(key, value, at)
            continue
        if blank_after_grid is not None:
            raise MbnInputError(
                f"{where}:{blank_after_grid}: blank line inside the grid (grid lines follow on"
                f" line {number})"
            )
        for col, ch in enumerate(line):
            if ch not in GRID_CHARS:
                raise MbnInputError(
                    f"{at}: unknown character {ch!r} in column {col + 1}"
                    f" (expected one of {' '.join(GRID_CHARS)})"
                )
        grid_lines.append((number, line))
    if not grid_lines:
        raise MbnInputError(f"{where}: no grid (the file has no maze lines)")

    cell = float(header.get("cell", DEFAULT_CELL))
    rows = len(grid_lines)
    cols = max(len(line) for _, line in grid_lines)
    grid = np.full((rows, cols), "#", dtype="<U1")
    for r, (_, line) in enumerate(grid_lines):
        grid[r, : len(line)] = list(line)
    if not np.any(grid != "#"):
        raise MbnInputError(
            f"{where}:{grid_lines[0][0]}: no free cell in the grid (every cell is '#')"
        )

    tiles: list[Tile] = []
    tile_labels: list[str] = []
    starts: list[tuple[float, float, float]] = []
    start_labels: list[str] = []
    for r in range(rows):
        for c in range(cols):
            ch = str(grid[r, c])
            if ch in "#.":
                continue
            x = (c + 0.5) * cell
            y = (rows - 1 - r + 0.5) * cell
            label = f"{where}:{grid_lines[r][0]}"
            if ch in START_HEADINGS:
                starts.append((x, y, START_HEADINGS[ch]))
                start_labels.append(f"{label}: start #{len(starts)} ({ch!r} in column {c + 1})")
            else:
                tiles.append(
                    Tile(
                        x=x,
                        y=y,
                        colors=int(ch),
                        width=cell,
                        length=DEFAULT_TILE_LENGTH,
                        heading=grid_tile_heading(grid, r, c),
                    )
                )
                tile_labels.append(f"{label}: tile #{len(tiles)} ({ch!r} in column {c + 1})")

    maze_name = str(header.get("name", name if name is not None else Path(where).stem))
    maze = Maze(
        name=maze_name,
        walls=merge_cells(grid == "#", cell),
        bounds=(0.0, cols * cell, 0.0, rows * cell),
        outside_is_wall=True,
        tiles=tuple(tiles),
        starts=np.array(starts, dtype=np.float64).reshape(-1, 3),
        grid=grid,
        cell=cell,
        source=source or where,
    )
    validate_maze(maze, where, start_labels=start_labels, tile_labels=tile_labels)
    return maze


def read_maze_file(path: str | os.PathLike[str]) -> Maze:
    """Read a ``.maze`` file (see the module docstring)."""
    text = read_text(path)
    return parse_maze_text(text, str(path), name=Path(path).stem, source=str(path))


# ---------------------------------------------------------------------------------------------
# TOML mazes

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


def _toml_error(exc: tomllib.TOMLDecodeError, text: str, where: str) -> MbnInputError:
    """A TOML syntax error as ``"{where}:{line}: message (column c)"``."""
    message = str(exc)
    match = re.search(r"\s*\(at line (\d+), column (\d+)\)\s*$", message)
    if match is not None:
        body = message[: match.start()]
        return MbnInputError(
            f"{where}:{match.group(1)}: TOML syntax error: {body} (column {match.group(2)})"
        )
    match = re.search(r"\s*\(at end of document\)\s*$", message)
    if match is not None:
        last = max(1, len(text.splitlines()))
        body = message[: match.start()]
        return MbnInputError(f"{where}:{last}: TOML syntax error: {body} (at end of file)")
    lineno = getattr(exc, "lineno", None)
    if isinstance(lineno, int):
        return MbnInputError(f"{where}:{lineno}: TOML syntax error: {message}")
    return MbnInputError(f"{where}: TOML syntax error: {message}")


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise MbnInputError(f"{what} must be a number, got {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise MbnInputError(f"{what} must be finite, got {value!r}")
    return out


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
        raise _toml_error(exc, text, where) from None

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
        if colors not in (1.0, 2.0):
            raise MbnInputError(f"{label}: colors must be 1 or 2, got {colors:g}")
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
    return _number(value, f"{label}: {key}")


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


# ---------------------------------------------------------------------------------------------
# the loader


def load_maze(spec: str | os.PathLike[str]) -> Maze:
    """A maze by built-in name (:data:`mbn.world.mazes.builtin.BUILTIN_NAMES`) or from a ``.maze``,
    ``.toml`` or Player/Stage ``.world`` file.

    A string that is a built-in name is that built-in; anything else is a path.
    """
    from mbn.world.mazes.builtin import BUILTIN_NAMES, builtin_maze

    if isinstance(spec, str) and spec in BUILTIN_NAMES:
        return builtin_maze(spec)
    path = Path(spec)
    suffix = path.suffix.lower()
    if not path.exists():
        if suffix in MAZE_SUFFIXES:
            raise MbnInputError(f"{path}: no such file")
        raise MbnInputError(
            f"unknown maze {str(spec)!r}: neither a built-in ({', '.join(BUILTIN_NAMES)}) nor an"
            f" existing {'/'.join(MAZE_SUFFIXES)} file"
        )
    if suffix == ".maze":
        return read_maze_file(path)
    if suffix == ".toml":
        return read_toml_maze(path)
    if suffix == ".world":
        from mbn.world.mazes.stage import read_stage_world

        return read_stage_world(path)
    raise MbnInputError(
        f"{path}: cannot tell the maze format from the suffix {path.suffix!r}"
        f" (expected {', '.join(MAZE_SUFFIXES)})"
    )
