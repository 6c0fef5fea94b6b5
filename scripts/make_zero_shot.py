"""Build the zero-shot suite of hand-made mazes (``docs/generalization.md``, "Zero-shot suite"):
grids unlike the generator's (long corridors, dense junctions, a pillared hall crossed by
corridors, a spiral, a comb of dead ends, a staircase of corners, tiles far from junctions),
with start marks placed by :func:`mbn.world.mazes.families.place_starts` (judgeable under every
rule of the family the maze serves) and tiles placed by a seeded draw at this script's edge.

The suite is frozen: the ``.maze`` files this script wrote are shipped in ``mbn/data/mazes``
and read as built-ins; this script documents how they were made, and rerunning it writes the
same files (``tests/world/mazes/test_families.py`` checks that).

Usage: python scripts/make_zero_shot.py [--out DIR] [--check]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from mbn.world.junctions import mask_neighbours
from mbn.world.mazes import families

#: What each maze is, for its header comment and the built-in description.
DESCRIPTIONS = {
    "zs_long": "long corridors (up to 16 cells between junctions), T junctions and corners",
    "zs_dense": "a lattice of one-cell pillars: plus crossings one cell apart everywhere",
    "zs_hall": "a pillared hall crossed by four long corridors",
    "zs_spiral": "a double spiral: corner after corner, dead ends at both ends",
    "zs_comb": "a loop with a comb of short dead ends along two of its corridors",
    "zs_stairs": "a staircase of corners beside a long loop",
    "zs_far_tiles2": "long corridors, one- and two-colour tiles 4 to 9 cells before junctions",
    "zs_dense_tiles2": "the pillared lattice with one- and two-colour tiles between crossings",
    "zs_far_tiles3": "long corridors, tiles of one, two and three colours far from junctions",
}


def _canvas(rows: int, cols: int) -> np.ndarray:
    return np.full((rows, cols), "#", dtype="<U1")


def _h(g: np.ndarray, r: int, c0: int, c1: int) -> None:
    g[r, c0 : c1 + 1] = "."


def _v(g: np.ndarray, c: int, r0: int, r1: int) -> None:
    g[r0 : r1 + 1, c] = "."


def grids() -> dict[str, np.ndarray]:
    """The suite's corridors (``#`` wall, ``.`` free), before tiles and start marks."""
    out = {}
    g = _canvas(15, 35)
    _h(g, 1, 1, 33), _h(g, 13, 1, 33), _h(g, 7, 1, 33)
    _v(g, 1, 1, 13), _v(g, 33, 1, 13), _v(g, 17, 1, 7), _v(g, 9, 7, 13), _v(g, 26, 7, 13)
    out["zs_long"] = g
    g = _canvas(17, 17)
    g[1:16, 1:16] = "."
    g[2:15:2, 2:15:2] = "#"
    out["zs_dense"] = g
    g = _canvas(21, 27)
    _h(g, 1, 1, 25), _h(g, 19, 1, 25), _v(g, 1, 1, 19), _v(g, 25, 1, 19)
    g[6:15, 8:19] = "."
    g[7:14:2, 9:18:2] = "#"
    _h(g, 10, 1, 8), _h(g, 10, 18, 25), _v(g, 13, 1, 6), _v(g, 13, 14, 19)
    out["zs_hall"] = g
    g = _canvas(19, 19)
    _h(g, 1, 1, 17), _v(g, 17, 1, 17), _h(g, 17, 1, 17), _v(g, 1, 3, 17)
    _h(g, 3, 1, 15), _v(g, 15, 3, 15), _h(g, 15, 3, 15), _v(g, 3, 5, 15)
    _h(g, 5, 3, 13), _v(g, 13, 5, 13), _h(g, 13, 5, 13), _v(g, 5, 7, 13)
    _h(g, 7, 5, 11), _v(g, 11, 7, 11), _h(g, 11, 7, 11)
    out["zs_spiral"] = g
    g = _canvas(11, 31)
    _h(g, 1, 1, 29), _h(g, 9, 1, 29), _v(g, 1, 1, 9), _v(g, 29, 1, 9), _h(g, 5, 1, 29)
    for c in range(4, 28, 4):
        _v(g, c, 2, 3)
    for c in range(6, 28, 4):
        _v(g, c, 6, 7)
    out["zs_comb"] = g
    g = _canvas(21, 21)
    r = c = 1
    while r < 19 and c < 19:
        _h(g, r, c, c + 2), _v(g, c + 2, r, r + 2)
        r, c = r + 2, c + 2
    _h(g, 19, 1, 19), _v(g, 1, 1, 19), _v(g, 19, r, 19)
    out["zs_stairs"] = g
    out["zs_far_tiles2"] = out["zs_long"].copy()
    out["zs_dense_tiles2"] = out["zs_dense"].copy()
    out["zs_far_tiles3"] = out["zs_long"].copy()
    return out


#: The family each maze serves (its start marks are judgeable under that family's rules).
FAMILY = {
    "zs_far_tiles2": "tiles2",
    "zs_dense_tiles2": "tiles2",
    "zs_far_tiles3": "tiles3",
}


def _far_tiles(g: np.ndarray, kinds: tuple[int, ...], rng: np.random.Generator) -> None:
    """Two tiles of each kind on straight cells 4 or more cells from the nearest junction
    along their corridor, no two side by side."""
    free = g != "#"
    maze_free = free.copy()
    nb = mask_neighbours(maze_free)
    straight = families.straight_cells(maze_free)
    options = [
        (int(r), int(c))
        for r, c in np.argwhere(straight)
        if min(families.run_to_end(straight, int(r), int(c), h) for h in range(4) if nb[r, c, h])
        >= 4
    ]
    taken: set[tuple[int, int]] = set()
    for kind in kinds:
        for _ in range(2):
            ok = [
                o
                for o in options
                if o not in taken
                and all(
                    (o[0] + dr, o[1] + dc) not in taken
                    for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1))
                )
            ]
            cell = ok[int(rng.integers(len(ok)))]
            taken.add(cell)
            g[cell] = str(kind)


def _between_tiles(g: np.ndarray, kinds: tuple[int, ...], rng: np.random.Generator) -> None:
    """Seven tiles of each kind on the one-cell corridors between crossings."""
    straight = families.straight_cells(g != "#")
    cells = [tuple(map(int, rc)) for rc in np.argwhere(straight)]
    order = rng.permutation(len(cells))
    k = 0
    for kind in kinds:
        for _ in range(7):
            while g[cells[order[k]]] != ".":
                k += 1
            g[cells[order[k]]] = str(kind)
            k += 1


def build(name: str, g: np.ndarray, seed: int) -> str:
    fam = families.family(FAMILY.get(name, "grid"))
    rng = np.random.default_rng(seed)
    g = g.copy()
    if name.startswith("zs_far"):
        _far_tiles(g, fam.tile_kinds, rng)
    elif name == "zs_dense_tiles2":
        _between_tiles(g, fam.tile_kinds, rng)
    for r, c, h in families.place_starts(fam, g, rng, name):
        g[r, c] = families.START_MARKS[h]
    head = [
        f"; {name}: a zero-shot maze, hand-made, unlike the generator's output:",
        f"; {DESCRIPTIONS[name]}.",
        f"; Start marks judgeable under every rule of the family {fam.name!r}. Made by",
        f"; `python scripts/make_zero_shot.py` (seed {seed}); only ever a test.",
        f"name = {name}",
        f"cell = {fam.cell:g}",
    ]
    return "\n".join([*head, *("".join(row) for row in g)]) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("src/mbn/data/mazes"))
    parser.add_argument(
        "--check", action="store_true", help="compare with the files, write nothing"
    )
    args = parser.parse_args()
    differ = []
    for i, (name, g) in enumerate(grids().items()):
        text = build(name, g, seed=i)
        path = args.out / f"{name}.maze"
        if args.check:
            if not path.exists() or path.read_text() != text:
                differ.append(name)
        else:
            path.write_text(text)
            print(f"wrote {path}")
    if differ:
        print(f"differ from the files: {', '.join(differ)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
