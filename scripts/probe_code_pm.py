"""How often does the code program module's DE end short of its codes? A probe
(docs/evidence.md, "Programs against dynamics", seed 10).

Runs the DE of the three-behaviour MBN's code program module (``evolve_code_pm``: the program
reward without the robot, the default ``[de]``, ``[contest3] pm_bound`` and ``switch_seconds``)
from ``--keys`` independent keys for ``--generations`` generations, all at once, and prints the
best program reward of each run at a few generations, and how many runs are still short of the
codes' level (below ``--short``). With ``--population CHECKPOINT`` (a ``contest3_pm.npz`` or
``mbn3_pm.npz`` of a run), every key runs on from that checkpoint's population instead.

Usage: python scripts/probe_code_pm.py [--keys 20] [--generations 6000] [--seed 2026]
[--population runs/pvd/seed-10/checkpoints/contest3_pm.npz]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--keys", type=int, default=20, help="independent DE runs")
    parser.add_argument("--generations", type=int, default=6000)
    parser.add_argument("--seed", type=int, default=2026, help="the runs' keys are split from it")
    parser.add_argument("--bound", type=float, default=10.0, help="[contest3] pm_bound")
    parser.add_argument("--switch", type=float, default=0.3, help="[contest3] switch_seconds")
    parser.add_argument("--short", type=float, default=-1e-3, help="a reward below it is short")
    parser.add_argument("--population", type=Path, default=None)
    args = parser.parse_args(argv)
    if args.keys < 1 or args.generations < 1:
        print("probe_code_pm: --keys and --generations must be at least 1", file=sys.stderr)
        return 2

    import jax

    from mbn.evolution.de import DEConfig, minimize
    from mbn.experiments.stages.mbn3 import code_pm_fitness
    from mbn.experiments.stages.settings import DESettings

    genome, fitness = code_pm_fitness(3, args.switch)
    de = DESettings()  # the default [de], as the stage's de_config reads it
    config = DEConfig(
        num_dims=genome.size,
        popsize=de.popsize,
        F=de.F,
        CR=de.CR,
        maximize=True,
        lower=-args.bound,
        upper=args.bound,
        init_low=-args.bound,
        init_high=args.bound,
    )
    population = None
    if args.population is not None:
        try:
            population = np.load(args.population)["population"]
        except (OSError, KeyError, ValueError) as e:
            print(f"{args.population}: not a DE checkpoint ({e})", file=sys.stderr)
            return 2
    keys = jax.random.split(jax.random.key(args.seed), args.keys)
    start = time.perf_counter()
    if population is None:
        run = jax.vmap(lambda k: minimize(fitness, k, config, args.generations)[1])
    else:
        run = jax.vmap(
            lambda k: minimize(fitness, k, config, args.generations, population=population)[1]
        )
    history = np.asarray(jax.jit(run)(keys))
    seconds = time.perf_counter() - start
    marks = sorted({g for g in (500, 1000, 1500, 3000, 4500, 6000) if g < args.generations})
    marks.append(args.generations)
    at = {g: history[:, g - 1] for g in marks}
    for g, v in at.items():
        short = int((v < args.short).sum())
        print(f"generation {g:>6}: {short} of {args.keys} runs short; worst {v.min():.3g}")
    print(
        json.dumps(
            {
                "keys": args.keys,
                "seed": args.seed,
                "population": None if args.population is None else str(args.population),
                "seconds": round(seconds, 1),
                "best": {str(g): [float(x) for x in v] for g, v in at.items()},
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
