"""Draw three train mazes of each maze family and the zero-shot suite's hand-made mazes, for
``docs/generalization.md`` (``evidence/generalization/families.png``, ``zero_shot.png``).

Usage: python scripts/draw_families.py [--out evidence/generalization]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from mbn.viz.maze import draw_maze
from mbn.world.mazes import families
from mbn.world.mazes.builtin import builtin_maze


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("evidence/generalization"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    names = list(families.FAMILIES)
    fig, axes = plt.subplots(len(names), 3, figsize=(15, 5 * len(names)))
    for row, name in zip(axes, names, strict=True):
        for ax, seed in zip(row, (0, 1, 2), strict=True):
            draw_maze(families.generate(name, seed), ax, title=f"{name}:{seed} (train)")
    fig.tight_layout()
    fig.savefig(args.out / "families.png", dpi=60)
    suite = [n for name in names for n in families.ZERO_SHOT.get(name, ()) if n.startswith("zs_")]
    fig, axes = plt.subplots(3, 3, figsize=(15, 13))
    for ax, name in zip(axes.ravel(), suite, strict=True):
        draw_maze(builtin_maze(name), ax, title=name)
    fig.tight_layout()
    fig.savefig(args.out / "zero_shot.png", dpi=60)
    print(f"wrote {args.out / 'families.png'} and {args.out / 'zero_shot.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
