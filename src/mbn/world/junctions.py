"""Junction analysis of grid mazes (NumPy): decision cells, wall-following rule exits, and the
sequence of junctions a trajectory passes.

Definitions (cells of :attr:`Maze.grid`, square or, for a maze whose blocks are not whole
multiples of its corridor width, columns and rows of their own widths: :meth:`Maze.grid_edges`;
the grid lies where the maze does; outside it is wall):

* A **decision cell** is a free cell with three or more free 4-neighbours (a T or a plus
  crossing), or exactly two at a right angle (a corner, where the robot must turn). A straight
  corridor cell (two opposite free neighbours) and a dead end (one) are not decision cells.
* Compass headings are ``'N' 'E' 'S' 'W'`` (indices 0..3 in that order); a robot *entering* a
  cell while moving north has heading ``'N'``. Exits are relative to that heading: ``'right'``,
  ``'straight'``, ``'left'``, ``'back'``.
* The **right-hand rule** takes the first open exit of right, straight, left (else back); the
  **left-hand rule** the first of left, straight, right (else back); any other priority order of
  the three exits is a rule too (:mod:`mbn.world.rules`).
* A **junction pass** (:func:`junction_sequence`): the robot's cell is the grid cell containing
  its ``(x, y)``; a pass begins when the robot moves into a decision cell from another cell and
  ends when it moves into a different cell; entry heading and exit are the compass directions of
  those two moves (for a move between cells that are not 4-neighbours, the dominant axis of the
  displacement between cell centres). A robot that wobbles back and forth across a border of a
  decision cell makes one pass per entry (each with exit ``'back'``) unless ``margin`` is given;
  a pass still open at the end of the trajectory, and a trajectory's first cell, are not
  reported as passes.

The jitted rollout engine (:mod:`mbn.world.rollout`) needs the same rules as arrays indexed per
cell: :func:`junction_tables` gives, for every cell and each of the four entry headings, the exit
code of the right and the left rule (0 back, 1 right, 2 straight, 3 left; -1 where the cell is not
a decision cell) and the mask of open exits (any rule's exit, :mod:`mbn.world.rules`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mbn.errors import MbnInputError
from mbn.world.mazes.model import Maze
from mbn.world.rules import Rule, open_mask, parse_rule

__all__ = [
    "EXITS",
    "EXIT_CODES",
    "HEADINGS",
    "STEPS",
    "JunctionPass",
    "RoutePass",
    "cell_of",
    "decision_cells",
    "free_neighbours",
    "junction_sequence",
    "junction_tables",
    "mask_neighbours",
    "program_swaps_caught",
    "route_passes",
    "rule_exit",
    "rule_route",
]

#: Compass headings in index order (also the order of the last axis of the junction tables).
HEADINGS = ("N", "E", "S", "W")
#: Exits relative to the entry heading.
EXITS = ("back", "right", "straight", "left")
#: Small-integer code of each exit, as in :func:`junction_tables`.
EXIT_CODES = {name: code for code, name in enumerate(EXITS)}

#: (d_row, d_col) of a move in each compass direction of :data:`HEADINGS`; row 0 is north.
STEPS = ((-1, 0), (0, 1), (1, 0), (0, -1))
# relative turn (compass offset from the entry heading) of each exit, and the rule orders
_TURN = {"straight": 0, "right": 1, "back": 2, "left": 3}


def _grid(maze: Maze) -> np.ndarray:
    if maze.grid is None or (maze.cell is None and maze.edges is None):
        raise MbnInputError(
            f"maze {maze.name!r}: junction analysis needs a grid maze (a .maze file, a grid"
            " built-in, or a maze given by rectangles made one by mbn.world.mazes.gridify)"
        )
    return np.asarray(maze.grid)


def free_neighbours(maze: Maze) -> np.ndarray:
    """``(R, C, 4)`` bool: whether each cell's neighbour to the N, E, S, W is free (outside the
    grid is wall)."""
    return mask_neighbours(_grid(maze) != "#")


def mask_neighbours(free: np.ndarray) -> np.ndarray:
    """:func:`free_neighbours` of a free-cell mask ``free`` ``(R, C)`` (a grid being built)."""
    padded = np.pad(free, 1, constant_values=False)
    rows, cols = free.shape
    out = np.empty((rows, cols, 4), dtype=bool)
    for h, (dr, dc) in enumerate(STEPS):
        out[..., h] = padded[1 + dr : 1 + dr + rows, 1 + dc : 1 + dc + cols]
    return out


def decision_cells(maze: Maze) -> np.ndarray:
    """``(R, C)`` bool: free cells with three or more free 4-neighbours, or exactly two at a right
    angle (corners)."""
    grid = _grid(maze)
    nb = free_neighbours(maze)
    count = nb.sum(axis=-1)
    straight = (nb[..., 0] & nb[..., 2]) | (nb[..., 1] & nb[..., 3])
    return (grid != "#") & ((count >= 3) | ((count == 2) & ~straight))


def cell_of(maze: Maze, x: float, y: float) -> tuple[int, int]:
    """The grid cell ``(row, col)`` containing the point ``(x, y)`` (row 0 north; a point on a
    border belongs to the cell east / north of it; points outside the grid give the nearest
    cell)."""
    grid = _grid(maze)
    rows, cols = grid.shape
    if maze.cell is not None:
        x0, _, y0, _ = maze.bounds
        i, j = math.floor((x - x0) / maze.cell), math.floor((y - y0) / maze.cell)
    else:
        xe, ye = maze.grid_edges()
        i = int(np.searchsorted(xe, x, side="right")) - 1
        j = int(np.searchsorted(ye, y, side="right")) - 1
    col = min(max(i, 0), cols - 1)
    row = rows - 1 - min(max(j, 0), rows - 1)
    return int(row), int(col)


def _heading_index(heading: str) -> int:
    try:
        return HEADINGS.index(heading)
    except ValueError:
        raise MbnInputError(f"heading must be one of N E S W, got {heading!r}") from None


def _open_exits(open_dirs: np.ndarray, h: int) -> set[str]:
    """The exits (relative to entry heading ``h``) whose neighbour is free."""
    return {name for name, turn in _TURN.items() if open_dirs[(h + turn) % 4]}


def _rule_exit_from(open_dirs: np.ndarray, h: int, rule: str | Rule) -> str:
    return parse_rule(rule).exit(_open_exits(open_dirs, h))


def rule_exit(
    maze: Maze,
    cell: tuple[int, int],
    heading: str,
    rule: str | Rule,
) -> str:
    """The exit (``'right' 'straight' 'left' 'back'``) that ``rule`` (a name or an order,
    :func:`mbn.world.rules.parse_rule`: e.g. the right-hand rule ``'right'``) takes in
    ``cell = (row, col)`` for a robot entering it while moving ``heading`` (``'N' 'E' 'S' 'W'``).

    Works for any free cell; in a corridor cell it is simply ``'straight'`` (or the way round a
    corner, or ``'back'`` at a dead end).
    """
    grid = _grid(maze)
    rule = parse_rule(rule)
    h = _heading_index(heading)
    r, c = cell
    rows, cols = grid.shape
    if not (0 <= r < rows and 0 <= c < cols):
        raise MbnInputError(f"cell {cell} is outside the {rows} x {cols} grid of {maze.name!r}")
    if grid[r, c] == "#":
        raise MbnInputError(f"cell {cell} of {maze.name!r} is a wall")
    return _rule_exit_from(free_neighbours(maze)[r, c], h, rule)


def junction_tables(maze: Maze) -> dict[str, np.ndarray]:
    """Per-cell tables for the jitted rollout engine.

    Returns:
        ``"right"``, ``"left"``: ``(R, C, 4)`` int8, the exit code (0 back, 1 right, 2 straight,
        3 left) the right- / left-hand rule takes in each cell for each entry heading (N, E, S, W
        order); -1 where the cell is not a decision cell.
        ``"open_mask"``: ``(R, C, 4)`` int8, the exits open there for each entry heading
        (:data:`mbn.world.rules.OPEN_BITS`; any rule's exit: :func:`mbn.world.rules.
        rule_exit_codes`); -1 where the cell is not a decision cell.
        ``"decision"``: ``(R, C)`` bool, :func:`decision_cells`.
        ``"open"``: ``(R, C, 4)`` bool, :func:`free_neighbours`.
    """
    nb = free_neighbours(maze)
    decision = decision_cells(maze)
    rows, cols = decision.shape
    tables = {rule: np.full((rows, cols, 4), -1, dtype=np.int8) for rule in ("right", "left")}
    mask = np.full((rows, cols, 4), -1, dtype=np.int8)
    for r, c in zip(*np.nonzero(decision), strict=True):
        for h in range(4):
            for rule, table in tables.items():
                table[r, c, h] = EXIT_CODES[_rule_exit_from(nb[r, c], h, rule)]
            mask[r, c, h] = open_mask(_open_exits(nb[r, c], h))
    return {
        "right": tables["right"],
        "left": tables["left"],
        "open_mask": mask,
        "decision": decision,
        "open": nb,
    }


@dataclass(frozen=True)
class JunctionPass:
    """One pass of the robot through a decision cell.

    Attributes:
        cell: ``(row, col)`` of the decision cell.
        entered_heading: compass direction of the move into the cell (``'N' 'E' 'S' 'W'``).
        exit: the exit taken, relative to ``entered_heading``.
        right_rule_exit, left_rule_exit: the exits the right- and left-hand rules take there.
        step_in: index of the first pose inside the cell.
        step_out: index of the first pose in the next cell.
    """

    cell: tuple[int, int]
    entered_heading: str
    exit: str
    right_rule_exit: str
    left_rule_exit: str
    step_in: int
    step_out: int


def _move_heading(a: tuple[int, int], b: tuple[int, int]) -> int:
    """Compass index of the move from cell ``a`` to cell ``b`` (dominant axis if not adjacent;
    ties go to the north-south axis)."""
    dr, dc = b[0] - a[0], b[1] - a[1]
    if abs(dr) >= abs(dc):
        return 0 if dr < 0 else 2
    return 1 if dc > 0 else 3


def _cell_track(maze: Maze, poses: np.ndarray, margin: float) -> list[tuple[int, int]]:
    """The cell of every pose; with ``margin > 0`` a move into a new cell counts only once the
    point is at least ``margin`` inside it (hysteresis against wobbling across a border)."""
    grid = _grid(maze)
    rows = grid.shape[0]
    xe, ye = maze.grid_edges()
    track: list[tuple[int, int]] = []
    current: tuple[int, int] | None = None
    for x, y in poses[:, :2]:
        candidate = cell_of(maze, float(x), float(y))
        if current is None or margin <= 0.0 or candidate == current:
            current = candidate
        else:
            r, c = candidate
            j = rows - 1 - r
            inside = min(x - xe[c], xe[c + 1] - x, y - ye[j], ye[j + 1] - y)
            if inside >= margin:
                current = candidate
        track.append(current)
    return track


def junction_sequence(maze: Maze, poses: np.ndarray, *, margin: float = 0.0) -> list[JunctionPass]:
    """The decision cells a trajectory passes, in order (see the module docstring).

    Args:
        maze: a grid maze.
        poses: ``(T, 3)`` (or ``(T, 2)``) robot poses; only ``x, y`` are used.
        margin: hysteresis (metres): the robot is taken to have moved into a new cell only once
            its point is at least this far inside it. 0 (default) uses the containing cell as is.

    Returns:
        One :class:`JunctionPass` per completed pass.
    """
    poses = np.asarray(poses, dtype=np.float64)
    if poses.ndim != 2 or poses.shape[1] < 2:
        raise MbnInputError(f"poses must be (T, 3), got shape {poses.shape}")
    if not np.all(np.isfinite(poses[:, :2])):
        raise MbnInputError("poses must be finite")
    if not math.isfinite(margin) or margin < 0:
        raise MbnInputError(f"margin must be >= 0, got {margin!r}")
    decision = decision_cells(maze)
    nb = free_neighbours(maze)
    track = _cell_track(maze, poses, margin)
    # runs of consecutive poses in the same cell: (cell, first step)
    runs: list[tuple[tuple[int, int], int]] = []
    for step, c in enumerate(track):
        if not runs or runs[-1][0] != c:
            runs.append((c, step))
    out: list[JunctionPass] = []
    for i in range(1, len(runs) - 1):
        cell, step_in = runs[i]
        if not decision[cell]:
            continue
        prev_cell, _ = runs[i - 1]
        next_cell, step_out = runs[i + 1]
        h_in = _move_heading(prev_cell, cell)
        h_out = _move_heading(cell, next_cell)
        exit_name = EXITS[[2, 1, 0, 3][(h_out - h_in) % 4]]
        out.append(
            JunctionPass(
                cell=(int(cell[0]), int(cell[1])),
                entered_heading=HEADINGS[h_in],
                exit=exit_name,
                right_rule_exit=_rule_exit_from(nb[cell], h_in, "right"),
                left_rule_exit=_rule_exit_from(nb[cell], h_in, "left"),
                step_in=step_in,
                step_out=step_out,
            )
        )
    return out


def _compass(theta: float) -> int:
    """Compass index (N E S W) nearest to the heading ``theta`` (radians from east)."""
    return (1 - round(theta / (math.pi / 2))) % 4


@dataclass(frozen=True)
class RoutePass:
    """One decision cell of a route walked by :func:`route_passes`: the rule in force when the
    robot enters it, where that rule came from (``source``: 0 the rule the walk started with,
    k the last tile driven over, of k colours), and the exits open there (relative to the entry
    heading)."""

    rule: str
    source: int
    open_exits: frozenset[str]


def rule_route(
    maze: Maze,
    start: tuple[float, float, float],
    rule: str | Rule,
    junctions: int,
    *,
    follow_tiles: bool = False,
    count_from_tile: bool = False,
    tile_rules: tuple[str, ...] = ("right", "left"),
) -> float | None:
    """The length (metres) of the route a wall follower drives from ``start = (x, y, theta)``
    until it leaves its ``junctions``-th decision cell, walking the grid cell by cell.

    From the start cell's centre (heading: the compass direction nearest ``theta``) the walk takes
    in every cell the exit of the rule in force (:func:`rule_exit`: in a corridor simply along
    it, round a corner, back at a dead end); each move is the distance between the two cells'
    centres (one ``cell`` in a grid of square cells), and the route ends half a cell past the
    centre of the ``junctions``-th decision cell entered
    (the start cell is not a pass, as in :func:`junction_sequence`). ``follow_tiles``: entering a
    cell with a tile makes its rule the one in force (``tile_rules[colours - 1]``; the paper's:
    one colour right, two colours left); a tile on a decision cell (a corner, say) only as the
    walk leaves that cell: the cell's pass is judged by the rule in force on entry, as a rollout
    records it (the tile in force when the robot's pose moves into the cell,
    :func:`mbn.world.stats.log_junctions`: the middle of its body, where the tile under it is
    read, is not on the tile yet).
    ``count_from_tile``: only decision cells entered after the first tile count.

    Returns None when the walk never gets there (it comes back to a cell with the same heading,
    rule and count: a loop without enough decision cells, or without a tile).
    """
    walk = _walk(maze, start, rule, junctions, follow_tiles, count_from_tile, tile_rules)
    return None if walk is None else walk[0]


def route_passes(
    maze: Maze,
    start: tuple[float, float, float],
    rule: str | Rule,
    junctions: int,
    *,
    follow_tiles: bool = False,
    count_from_tile: bool = False,
    tile_rules: tuple[str, ...] = ("right", "left"),
) -> list[RoutePass] | None:
    """The ``junctions`` decision cells counted on the route of :func:`rule_route` (same
    arguments), in order, each with the rule in force, where it came from and the exits open:
    what a test judging those junctions asks of the robot. A controller that follows another
    rule ``r`` wherever the rule in force came from a tile of k colours (a wrong program for
    that tile) drives the same route until the first pass of source k where ``r`` takes another
    exit, and fails the test there. None when the walk never gets there."""
    walk = _walk(maze, start, rule, junctions, follow_tiles, count_from_tile, tile_rules)
    return None if walk is None else walk[1]


def program_swaps_caught(
    maze: Maze,
    first: str | Rule,
    junctions: int,
    tile_rules: tuple[str, ...],
) -> dict[tuple[int, str], int]:
    """How well a test judges the programs of an MBN: for each tile kind k (``tile_rules[k -
    1]``) and each other rule ``w`` of ``tile_rules``, from how many of the maze's starts a
    controller that starts as ``first``, follows the tiles, and follows ``w`` after a k-colour
    tile (one program swapped for another) takes a wrong exit within the ``junctions`` judged
    (:func:`route_passes`). A start whose route never gets through them catches nothing."""
    rules = [parse_rule(r) for r in tile_rules]
    caught = {(k, w.name): 0 for k, r in enumerate(rules, 1) for w in rules if w != r}
    for start in maze.starts:
        passes = route_passes(
            maze, tuple(start), first, junctions, follow_tiles=True, tile_rules=tile_rules
        )
        for k, w in caught:
            wrong = parse_rule(w)
            caught[(k, w)] += any(
                p.source == k and wrong.exit(p.open_exits) != parse_rule(p.rule).exit(p.open_exits)
                for p in passes or ()
            )
    return caught


_Tables = tuple[np.ndarray, np.ndarray, np.ndarray, tuple[tuple[tuple[int, int], int], ...]]

#: The last few mazes' grid, free neighbours, decision cells and tile cells
#: (:func:`_walk_tables`).
_WALK_TABLES: list[tuple[Maze, _Tables]] = []


def _walk_tables(maze: Maze) -> _Tables:
    """``(grid, free_neighbours, decision_cells, tiles)`` of ``maze``, ``tiles`` each tile's
    cell and colours, kept for the last 8 mazes (a maze is frozen: the same object has the
    same tables), so that the many walks from one maze's starts compute them once."""
    for held, tables in _WALK_TABLES:
        if held is maze:
            return tables
    tiles = tuple((cell_of(maze, t.x, t.y), t.colors) for t in maze.tiles)
    tables = (_grid(maze), free_neighbours(maze), decision_cells(maze), tiles)
    _WALK_TABLES.insert(0, (maze, tables))
    del _WALK_TABLES[8:]
    return tables


def _walk(
    maze: Maze,
    start: tuple[float, float, float],
    rule: str | Rule,
    junctions: int,
    follow_tiles: bool,
    count_from_tile: bool,
    tile_rules: tuple[str, ...],
) -> tuple[float, list[RoutePass]] | None:
    """:func:`rule_route`'s walk: its length and the decision cells it counts."""
    if junctions < 1:
        raise MbnInputError(f"junctions must be >= 1, got {junctions!r}")
    grid, nb, decision, tiles = _walk_tables(maze)
    rows, cols = grid.shape
    # each cell's extent along the north-south axis (h % 2 == 0) and the east-west axis
    if maze.cell is not None:
        along = (np.full((rows, cols), maze.cell), np.full((rows, cols), maze.cell))
    else:
        xe, ye = maze.grid_edges()
        along = (
            np.repeat(np.diff(ye)[::-1][:, None], cols, 1),
            np.repeat(np.diff(xe)[None, :], rows, 0),
        )
    tile_rule: dict[tuple[int, int], tuple[str, int]] = {}
    names: dict[int, str] = {}  # each tile kind's rule, parsed once per walk
    for cell, colors in tiles:
        if follow_tiles and colors > len(tile_rules):
            raise MbnInputError(
                f"maze {maze.name!r}: a {colors}-colour tile, and tile_rules name rules for "
                f"tiles of up to {len(tile_rules)} colours"
            )
        if colors <= len(tile_rules):
            if colors not in names:
                names[colors] = parse_rule(tile_rules[colors - 1]).name
            tile_rule[cell] = (names[colors], colors)
    r, c = cell_of(maze, float(start[0]), float(start[1]))
    if grid[r, c] == "#":
        raise MbnInputError(f"maze {maze.name!r}: start {tuple(start)} is in a wall")
    h = _compass(float(start[2]))
    current: str = parse_rule(rule).name
    source = 0
    seen_tile = not count_from_tile
    passes: list[RoutePass] = []
    length = 0.0
    visited: set[tuple[int, int, int, str, int, int, bool]] = set()
    parsed: dict[str, Rule] = {}
    while True:
        key = (r, c, h, current, source, len(passes), seen_tile)
        if key in visited:
            return None
        visited.add(key)
        open_dirs = nb[r, c]
        if length > 0 and decision[r, c] and seen_tile:
            passes.append(RoutePass(current, source, frozenset(_open_exits(open_dirs, h))))
            if len(passes) == junctions:
                return length + float(along[h % 2][r, c]) / 2, passes
        if length == 0 and open_dirs[h]:
            exit_name = "straight"  # the start faces along its corridor
        else:
            if current not in parsed:
                parsed[current] = parse_rule(current)
            exit_name = parsed[current].exit(_open_exits(open_dirs, h))
        if length > 0 and follow_tiles and decision[r, c] and (r, c) in tile_rule:
            # a tile on a decision cell: in force as the walk leaves the cell
            current, source = tile_rule[(r, c)]
            seen_tile = True
        h = (h + _TURN[exit_name]) % 4
        if not open_dirs[h]:  # a closed cell
            return None
        was = float(along[h % 2][r, c])
        r, c = r + STEPS[h][0], c + STEPS[h][1]
        length += (was + float(along[h % 2][r, c])) / 2  # centre to centre
        if follow_tiles and (r, c) in tile_rule and not decision[r, c]:
            current, source = tile_rule[(r, c)]
            seen_tile = True
