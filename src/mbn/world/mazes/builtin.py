"""The built-in mazes: seven crossroads, the Stage reference arena, test and validation mazes.

* ``cross_L`` ... ``cross_LSR`` (:func:`crossroad`): a junction entered from the south with the
  given exits open (L left = west, S straight = north, R right = east); every arm is 3 cells
  (3.6 m) long and closed at its far end; one start at the south end facing north. Built as
  ``.maze`` text and read by :func:`mbn.world.mazes.grid_text.parse_maze_text`.
* ``stage_arena``: the arena of the Stage reference data (``docs/world.md``): five corridors,
  1.2 m wide, crossing in a plus, a T and two L turns, walled by 10 rectangles in
  [0, 14] x [0, 10.4]; six starts in corridor centres.
* ``fig4``, ``heldout``, ``validation`` and ``validation2``: grid mazes of one-cell corridors
  with plus, T and L crossings, tiles of both kinds and 8+ starts, shipped as ``.maze`` files
  in ``mbn/data/mazes``; ``heldout`` is kept out of training, the validation mazes out of
  every test.
* ``tiles3``, ``tiles3_heldout`` and ``tiles3_validation``: lattices of corridors with tiles of
  one, two and three colours, for rules beyond right and left; ``tiles3_heldout`` is kept out
  of training and choices, ``tiles3_validation`` out of every test.
* ``zs_*``: the zero-shot suite (:data:`mbn.world.mazes.families.ZERO_SHOT`), hand-made mazes
  unlike the generated ones (``scripts/make_zero_shot.py``), only ever a test.
"""

from __future__ import annotations

import math
from importlib import resources

import numpy as np

from mbn.errors import MbnInputError
from mbn.world.mazes.grid_text import parse_maze_text
from mbn.world.mazes.model import DEFAULT_CELL, TILE_COLORS, Maze
from mbn.world.mazes.validate import validate_maze

__all__ = [
    "ARENA_BOUNDS",
    "ARENA_CORRIDORS",
    "ARENA_STARTS",
    "ARENA_WALLS",
    "BUILTIN_NAMES",
    "CROSSROAD_KINDS",
    "builtin_maze",
    "crossroad",
    "crossroad_text",
    "describe_builtins",
    "stage_arena",
]

#: The seven crossroad kinds: the non-empty subsets of the exits left, straight, right.
CROSSROAD_KINDS = ("L", "S", "R", "LS", "LR", "SR", "LSR")
_CROSS_WORDS = {
    "L": "an L turn to the left",
    "S": "a straight corridor (no junction)",
    "R": "an L turn to the right",
    "LS": "a T: left or straight",
    "LR": "a T: left or right",
    "SR": "a T: straight or right",
    "LSR": "a plus crossing: left, straight or right",
}

#: The Stage reference arena's 10 wall rectangles ``(xmin, xmax, ymin, ymax)``, wall00..wall09.
ARENA_WALLS = np.array(
    [
        [0.0, 14.0, 0.0, 1.0],
        [0.0, 4.0, 1.0, 4.6],
        [5.2, 11.8, 1.0, 4.6],
        [13.0, 14.0, 1.0, 10.4],
        [0.0, 1.0, 4.6, 10.4],
        [1.0, 4.0, 5.8, 10.4],
        [5.2, 9.4, 5.8, 10.4],
        [10.6, 13.0, 5.8, 8.2],
        [4.0, 5.2, 9.4, 10.4],
        [9.4, 13.0, 9.4, 10.4],
    ]
)
#: Its free corridors H1, V1, V2, H2, V3 ``(xmin, xmax, ymin, ymax)``.
ARENA_CORRIDORS = np.array(
    [
        [1.0, 13.0, 4.6, 5.8],
        [4.0, 5.2, 1.0, 9.4],
        [9.4, 10.6, 5.8, 9.4],
        [10.6, 13.0, 8.2, 9.4],
        [11.8, 13.0, 1.0, 4.6],
    ]
)
#: Its bounds: the walls tile this box minus the corridors.
ARENA_BOUNDS = (0.0, 14.0, 0.0, 10.4)
#: Start poses on corridor centre lines, facing along the corridor.
ARENA_STARTS = np.array(
    [
        [2.2, 5.2, 0.0],  # H1, west part, facing east
        [4.6, 2.2, math.pi / 2],  # V1, south arm, facing north
        [4.6, 8.2, -math.pi / 2],  # V1, north arm, facing south
        [7.3, 5.2, math.pi],  # H1, between the plus and the T, facing west
        [10.0, 7.0, math.pi / 2],  # V2, facing north
        [12.4, 2.2, math.pi / 2],  # V3, facing north
    ]
)


def _normalise_kind(kind: str) -> str:
    k = kind[len("cross_") :] if kind.startswith("cross_") else kind
    if k not in CROSSROAD_KINDS:
        raise MbnInputError(
            f"unknown crossroad kind {kind!r} (expected one of"
            f" {', '.join('cross_' + c for c in CROSSROAD_KINDS)})"
        )
    return k


#: Ways into a crossroad's south arm (:func:`crossroad`).
APPROACHES = ("south", "west", "east", "near")


def check_approaches(approaches: tuple[str, ...]) -> None:
    """A non-empty tuple of distinct :data:`APPROACHES`, or one clear error naming it."""
    if not approaches or not set(approaches) <= set(APPROACHES):
        raise MbnInputError(
            f"approaches must be some of {', '.join(APPROACHES)}, got {approaches!r}"
        )
    if len(set(approaches)) != len(approaches):
        raise MbnInputError(f"approaches: listed twice in {approaches!r}")


def crossroad_text(
    kind: str, *, arm_cells: int = 3, tile: int | None = None, approach: str = "south"
) -> str:
    """The ``.maze`` grid of a crossroad (see :func:`crossroad`), without header."""
    k = _normalise_kind(kind)
    if approach not in APPROACHES:
        raise MbnInputError(f"approach must be one of {', '.join(APPROACHES)}, got {approach!r}")
    if approach != "south" and tile is not None:
        raise MbnInputError("a tile needs the approach from the south")
    if isinstance(arm_cells, bool) or not isinstance(arm_cells, int) or arm_cells < 1:
        raise MbnInputError(f"arm_cells must be an integer >= 1, got {arm_cells!r}")
    if tile is not None and tile not in TILE_COLORS:
        raise MbnInputError(
            f"tile must be one of {', '.join(map(str, TILE_COLORS))} or None, got {tile!r}"
        )
    if tile is not None and arm_cells < 2:
        raise MbnInputError("a tile needs arm_cells >= 2 (it lies one cell north of the start)")
    a = arm_cells
    size = 2 * a + 1
    grid = [["#"] * size for _ in range(size)]
    grid[a][a] = "."  # the junction cell
    for r in range(a + 1, size):
        grid[r][a] = "."  # the south arm
    if "S" in k:
        for r in range(a):
            grid[r][a] = "."
    if "L" in k:
        for c in range(a):
            grid[a][c] = "."
    if "R" in k:
        for c in range(a + 1, size):
            grid[a][c] = "."
    if approach == "south":
        grid[size - 1][a] = "^"
    elif approach == "near":  # one cell short of the junction, as a start mark in a maze may be
        grid[a + 1][a] = "^"
    else:  # a corridor along the south edge, entered at its far end, turning into the arm
        cols = range(a) if approach == "west" else range(a + 1, size)
        for c in cols:
            grid[size - 1][c] = "."
        grid[size - 1][0 if approach == "west" else size - 1] = ">" if approach == "west" else "<"
    if tile is not None:
        grid[size - 2][a] = str(tile)
    return "\n".join("".join(row) for row in grid) + "\n"


def crossroad(
    kind: str,
    *,
    arm_cells: int = 3,
    cell: float = DEFAULT_CELL,
    tile: int | None = None,
    approach: str = "south",
) -> Maze:
    """A crossroad entered from the south.

    The grid is ``(2 a + 1)`` cells square (``a = arm_cells``) with the junction at its centre:
    the south arm (``a`` cells), the junction cell, and the open arms (``a`` cells each, closed at
    the far end by the grid's edge). One start at the centre of the south end cell, facing north.

    Args:
        kind: ``"L" "S" "R" "LS" "LR" "SR" "LSR"`` (or with the ``cross_`` prefix): the open
            exits, left (west), straight (north), right (east).
        arm_cells: length of each arm in cells.
        cell: the cell side (metres).
        tile: 1 to 6 (:data:`~mbn.world.mazes.model.TILE_COLORS`) puts a tile of that many
            colours in the south arm one cell north of the start.
        approach: ``"south"`` (the paper's: the start is in the south arm, facing the junction),
            ``"west"`` or ``"east"``: the south arm's end cell opens onto a corridor of ``a``
            cells along the south edge, and the start is at that corridor's far end facing the
            arm, so the robot turns a corner (left from the west, right from the east) ``a``
            cells before the junction, as it does in a maze; ``"near"``: the start is in the
            south arm's cell next to the junction (1 cell from it; the robot starts from rest
            just short of it, as from some start marks of the test mazes).
    """
    k = _normalise_kind(kind)
    if not (isinstance(cell, int | float) and math.isfinite(cell) and cell > 0):
        raise MbnInputError(f"cell must be a finite number > 0, got {cell!r}")
    body = crossroad_text(k, arm_cells=arm_cells, tile=tile, approach=approach)
    name = f"cross_{k}" + (f"_tile{tile}" if tile is not None else "")
    name += {"south": "", "near": "_near"}.get(approach, f"_from_{approach}")
    text = f"name = {name}\ncell = {float(cell)!r}\n{body}"
    return parse_maze_text(text, f"<builtin {name}>", source="builtin")


def stage_arena() -> Maze:
    """The Stage reference arena (10 wall rectangles, corridors 1.2 m wide)."""
    maze = Maze(
        name="stage_arena",
        walls=ARENA_WALLS.copy(),
        bounds=ARENA_BOUNDS,
        outside_is_wall=True,
        starts=ARENA_STARTS.copy(),
        source="builtin",
    )
    validate_maze(maze, "<builtin stage_arena>")
    return maze


def _packaged(name: str) -> Maze:
    text = (resources.files("mbn.data") / "mazes" / f"{name}.maze").read_text(encoding="utf-8")
    return parse_maze_text(text, f"<builtin {name}>", name=name, source="builtin")


_DESCRIPTIONS: dict[str, str] = {
    **{
        f"cross_{k}": f"crossroad entered from the south: {_CROSS_WORDS[k]}; 3.6 m arms, 1 start"
        for k in CROSSROAD_KINDS
    },
    "stage_arena": "the Stage reference arena: plus, T and two L turns, 14 x 10.4 m, 6 starts",
    "fig4": "test maze after the paper's Fig. 4: plus, T and L crossings, tiles, 10 starts",
    "heldout": "a second fig4-style maze kept out of training: tiles, 12 starts",
    "validation": "a third fig4-style maze used by no test (to choose among candidates): 8 starts",
    "validation2": "a second validation maze (fig4's wall blocks), used by no test: 8 starts",
    "tiles3": "test maze with one-, two- and three-colour tiles: plus, T and L, 11 starts",
    "tiles3_heldout": "a second maze with three kinds of tile, kept out of training: 11 starts",
    "tiles3_validation": "a maze with three kinds of tile used by no test (to choose): 11 starts",
    "zs_long": "zero-shot: long corridors (up to 16 cells between junctions), 10 starts",
    "zs_dense": "zero-shot: a lattice of one-cell pillars, plus crossings everywhere, 10 starts",
    "zs_hall": "zero-shot: a pillared hall crossed by four long corridors, 10 starts",
    "zs_spiral": "zero-shot: a double spiral, corner after corner, 10 starts",
    "zs_comb": "zero-shot: a loop with a comb of short dead ends, 10 starts",
    "zs_stairs": "zero-shot: a staircase of corners beside a long loop, 10 starts",
    "zs_far_tiles2": "zero-shot: long corridors, tiles 4+ cells before junctions, 10 starts",
    "zs_dense_tiles2": "zero-shot: the pillared lattice with one- and two-colour tiles, 10 starts",
    "zs_far_tiles3": "zero-shot: long corridors, three tile kinds far from junctions, 10 starts",
}

#: The built-in mazes shipped as ``.maze`` files in ``mbn/data/mazes``.
_PACKAGED = (
    "fig4",
    "heldout",
    "validation",
    "validation2",
    "tiles3",
    "tiles3_heldout",
    "tiles3_validation",
    "zs_long",
    "zs_dense",
    "zs_hall",
    "zs_spiral",
    "zs_comb",
    "zs_stairs",
    "zs_far_tiles2",
    "zs_dense_tiles2",
    "zs_far_tiles3",
)

#: Names :func:`builtin_maze` knows, in order.
BUILTIN_NAMES: tuple[str, ...] = tuple(_DESCRIPTIONS)


def builtin_maze(name: str) -> Maze:
    """The built-in maze ``name`` (one of :data:`BUILTIN_NAMES`)."""
    if name.startswith("cross_") and name in BUILTIN_NAMES:
        return crossroad(name)
    if name == "stage_arena":
        return stage_arena()
    if name in _PACKAGED:
        return _packaged(name)
    raise MbnInputError(f"unknown built-in maze {name!r} (known: {', '.join(BUILTIN_NAMES)})")


def describe_builtins() -> list[tuple[str, str]]:
    """``(name, one-line description)`` of every built-in maze, in :data:`BUILTIN_NAMES` order."""
    return [(name, _DESCRIPTIONS[name]) for name in BUILTIN_NAMES]
