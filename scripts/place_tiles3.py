"""Seeded search for the tile and start placements of a three-tile maze (``tiles3``,
``tiles3_heldout``, ``tiles3_validation``; docs/mazes.md).

Keeps the maze's corridors, removes its tiles and start marks, and places (NumPy generator of
``--seed``) ``--per-kind`` tiles of each of one, two and three colours and ``--marks`` start
marks on straight corridor cells, marks ``--mark-gap`` cells or more from a junction, no two
items side by side. A local search from a random first placement (move one item or turn a mark
round, keep the move unless it does worse) prints the first placement, as ``.maze`` grid rows,
meeting what ``tests/world/mazes/test_builtin.py::test_the_three_tile_mazes`` asks:

* from every mark each of the rules right, left, straight-right and straight-left passes three
  junctions, and a robot starting as either wall follower, with tiles putting right, left and
  straight-right in force, drives over a tile and then through three junctions;
* the test judges the programs: for either first rule, a controller that follows another
  tile's rule after a tile of one kind (a program swapped) takes a wrong exit within the three
  junctions judged from at least ``--caught`` marks, for every kind and every other rule
  (:func:`mbn.world.junctions.program_swaps_caught`).

Usage: python scripts/place_tiles3.py tiles3 --seed 0
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from mbn.world.junctions import (
    decision_cells,
    free_neighbours,
    program_swaps_caught,
    rule_route,
)
from mbn.world.mazes.grid_text import parse_maze_text
from mbn.world.mazes.load import load_maze
from mbn.world.mazes.model import Maze

TILE_RULES = ("right", "left", "straight-right")
FIRST_RULES = ("right", "left")
MARKS = {(-1, 0): "^", (1, 0): "v", (0, 1): ">", (0, -1): "<"}


def score(maze: Maze, caught: int) -> int:
    """-1 when a route of the first condition fails; else how far the program-swap counts reach
    ``caught`` (the sum of min(count, caught) over the first rules, kinds and other rules)."""
    for start in maze.starts:
        for rule in ("right", "left", "straight-right", "straight-left"):
            if rule_route(maze, tuple(start), rule, 3) is None:
                return -1
        for first in FIRST_RULES:
            route = rule_route(
                maze,
                tuple(start),
                first,
                3,
                follow_tiles=True,
                count_from_tile=True,
                tile_rules=TILE_RULES,
            )
            if route is None:
                return -1
    return sum(
        min(count, caught)
        for first in FIRST_RULES
        for count in program_swaps_caught(maze, first, 3, TILE_RULES).values()
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("maze", help="a built-in three-tile maze whose corridors are kept")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--per-kind", type=int, default=4)
    parser.add_argument("--marks", type=int, default=11)
    parser.add_argument("--caught", type=int, default=4)
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument(
        "--mark-gap",
        type=int,
        choices=(1, 2),
        default=2,
        help="cells from a mark to the nearest junction, at least (default 2)",
    )
    args = parser.parse_args(argv)
    base = load_maze(args.maze)
    grid = np.where(base.grid == "#", "#", ".")
    bare = parse_maze_text(_text(base.name, base.cell, grid), base.name)
    nb = free_neighbours(bare)
    decision = decision_cells(bare)
    corridor = [
        (int(r), int(c))
        for r, c in zip(*np.nonzero((bare.grid != "#") & ~decision), strict=True)
        if nb[r, c].sum() == 2
    ]
    vertical = {cell: bool(nb[cell][0]) for cell in corridor}

    def far_from_junction(cell: tuple[int, int]) -> bool:
        r, c = cell
        steps = ((-1, 0), (1, 0)) if vertical[cell] else ((0, -1), (0, 1))
        return not any(decision[r + dr, c + dc] for dr, dc in steps)

    mark_cells = [cell for cell in corridor if args.mark_gap == 1 or far_from_junction(cell)]
    rng = np.random.default_rng(args.seed)
    n_tiles = 3 * args.per_kind
    kinds = [1 + i // args.per_kind for i in range(n_tiles)]

    def apart(cell: tuple[int, int], others: list[tuple[int, int]]) -> bool:
        return all(abs(cell[0] - o[0]) + abs(cell[1] - o[1]) >= 2 for o in others)

    def draw(pool: list[tuple[int, int]], others: list[tuple[int, int]]) -> tuple[int, int]:
        for _ in range(100_000):
            cell = pool[int(rng.integers(len(pool)))]
            if apart(cell, others):
                return cell
        raise SystemExit(f"{base.name}: no room for {n_tiles} tiles and {args.marks} marks apart")

    # a first placement: items drawn one by one, each apart from those before it
    cells: list[tuple[int, int]] = []
    for i in range(n_tiles + args.marks):
        cells.append(draw(corridor if i < n_tiles else mark_cells, cells))
    heads = [int(rng.integers(2)) for _ in range(args.marks)]

    def build() -> Maze:
        g = grid.copy()
        for cell, kind in zip(cells, kinds, strict=False):
            g[cell] = str(kind)
        for cell, head in zip(cells[n_tiles:], heads, strict=True):
            steps = [(-1, 0), (1, 0)] if vertical[cell] else [(0, -1), (0, 1)]
            g[cell] = MARKS[steps[head]]
        return parse_maze_text(_text(base.name, base.cell, g), base.name)

    goal = args.caught * 6 * len(FIRST_RULES)
    best = score(build(), args.caught)
    # local search: move one item (or turn a mark round), keep the move unless the score drops
    for step in range(1, args.steps + 1):
        if best == goal:
            maze = build()
            print(f"# seed {args.seed}: placement after {step - 1} moves", file=sys.stderr)
            for first in FIRST_RULES:
                counts = program_swaps_caught(maze, first, 3, TILE_RULES)
                print(f"# first rule {first}: {counts}", file=sys.stderr)
            print("\n".join("".join(row) for row in np.asarray(maze.grid)))
            return 0
        i = int(rng.integers(n_tiles + args.marks))
        old_cell, old_heads = cells[i], list(heads)
        if i >= n_tiles and rng.random() < 0.3:
            heads[i - n_tiles] ^= 1
        else:
            others = cells[:i] + cells[i + 1 :]
            cells[i] = draw(corridor if i < n_tiles else mark_cells, others)
        new = score(build(), args.caught)
        if new >= best:
            best = new
        else:
            cells[i], heads = old_cell, old_heads
    print(f"no placement in {args.steps} moves (score {best} of {goal})", file=sys.stderr)
    return 1


def _text(name: str, cell: float, grid: np.ndarray) -> str:
    rows = "\n".join("".join(row) for row in grid)
    return f"name = {name}\ncell = {cell}\n{rows}\n"


if __name__ == "__main__":
    raise SystemExit(main())
