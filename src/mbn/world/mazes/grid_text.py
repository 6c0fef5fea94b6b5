"""The ``.maze`` text grid: a grid of square cells, one character each.

::

    ; a T junction: comments start with ';'
    cell = 1.2          ; optional header lines "key = value" before the grid: cell, name
    name = tee
    #######
    .......
    ###1###
    ###^###

* ``#`` wall, ``.`` free, ``1`` to ``6`` free with a tile of that many colours (``1`` one
  colour, ``2`` two, ... :data:`~mbn.world.mazes.model.TILE_COLORS`), ``>`` ``<`` ``^`` ``v``
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
  :data:`~mbn.world.mazes.model.DEFAULT_TILE_LENGTH` long; on a corner (two free neighbours at a
  right angle) ``cell`` long, the whole cell, so that a robot turning there drives over it
  however it cuts the corner (:func:`grid_tile_length`). Its heading (the corridor's direction) is
  east (0) when the cell has more free east/west neighbours than north/south ones, and north (pi/2)
  otherwise. So the heading is pi/2 in a north-south corridor and at a dead end open to the north or
  south; 0 in an east-west corridor; in a T junction it follows the T's bar (the side with two free
  neighbours); ties (a plus crossing, an L corner, an isolated cell) give pi/2.

Every maze read here passes :func:`~mbn.world.mazes.validate.validate_maze`.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np

from mbn.errors import MbnInputError
from mbn.world.mazes.model import (
    DEFAULT_CELL,
    DEFAULT_TILE_LENGTH,
    TILE_COLORS,
    Maze,
    Tile,
    merge_cells,
)
from mbn.world.mazes.validate import read_text, validate_maze

__all__ = [
    "GRID_CHARS",
    "START_HEADINGS",
    "grid_shape",
    "grid_tile_heading",
    "grid_tile_length",
    "parse_maze_text",
    "read_maze_file",
]

#: The characters of a ``.maze`` grid, in the order error messages list them.
GRID_CHARS = ("#", ".", *(str(c) for c in TILE_COLORS), ">", "<", "^", "v")
#: Heading (radians) of the start pose each start mark stands for.
START_HEADINGS = {">": 0.0, "<": math.pi, "^": math.pi / 2, "v": -math.pi / 2}

_GRID_SET = frozenset(GRID_CHARS)
_HEADER_RE = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*([^;]*?)\s*(;.*)?$")


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


def grid_tile_length(grid: np.ndarray, row: int, col: int, cell: float) -> float:
    """The length (along its heading) of a tile in cell ``(row, col)`` of a grid of cells of side
    ``cell``: the whole cell on a corner (exactly two free neighbours, at a right angle),
    :data:`~mbn.world.mazes.model.DEFAULT_TILE_LENGTH` elsewhere."""
    rows, cols = grid.shape

    def free(r: int, c: int) -> bool:
        return 0 <= r < rows and 0 <= c < cols and grid[r, c] != "#"

    north, south = free(row - 1, col), free(row + 1, col)
    west, east = free(row, col - 1), free(row, col + 1)
    corner = (north != south) and (west != east)
    return cell if corner else DEFAULT_TILE_LENGTH


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


def _split(text: str, where: str) -> tuple[dict[str, float | str], list[tuple[int, str]]]:
    """The header (key: value) and the grid lines ``(1-based line number, text)`` of a ``.maze``
    text, or the one-line error of its first bad line."""
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
        if not _GRID_SET.issuperset(line):
            col, ch = next((c, ch) for c, ch in enumerate(line) if ch not in _GRID_SET)
            raise MbnInputError(
                f"{at}: unknown character {ch!r} in column {col + 1}"
                f" (expected one of {' '.join(GRID_CHARS)})"
            )
        grid_lines.append((number, line))
    if not grid_lines:
        raise MbnInputError(f"{where}: no grid (the file has no maze lines)")
    return header, grid_lines


def grid_shape(path: str | os.PathLike[str]) -> tuple[int, int]:
    """The ``(rows, columns)`` of a ``.maze`` file's grid, from its lines alone (a quick look
    before reading it, e.g. to refuse a grid too large to draw)."""
    _, grid_lines = _split(read_text(path), str(path))
    return len(grid_lines), max((len(line) for _, line in grid_lines), default=0)


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
    header, grid_lines = _split(text, where)
    cell = float(header.get("cell", DEFAULT_CELL))
    rows = len(grid_lines)
    cols = max(len(line) for _, line in grid_lines)
    grid = np.full((rows, cols), "#", dtype="<U1")
    for r, (_, line) in enumerate(grid_lines):
        grid[r, : len(line)] = list(line)
    free = grid != "#"
    if not np.any(free):
        raise MbnInputError(
            f"{where}:{grid_lines[0][0]}: no free cell in the grid (every cell is '#')"
        )
    if not (np.any(free[1:] & free[:-1]) or np.any(free[:, 1:] & free[:, :-1])):
        raise MbnInputError(
            f"{where}:{grid_lines[0][0]}: no corridor: no two free cells side by side (each is "
            "walled in on four sides, e.g. a checkerboard); a maze needs free cells to drive "
            "between"
        )

    tiles: list[Tile] = []
    tile_labels: list[str] = []
    starts: list[tuple[float, float, float]] = []
    start_labels: list[str] = []
    for r, c in zip(*np.nonzero(grid > "."), strict=True):  # digits and start marks, row-major
        r, c = int(r), int(c)
        ch = str(grid[r, c])
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
                    length=grid_tile_length(grid, r, c, cell),
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
