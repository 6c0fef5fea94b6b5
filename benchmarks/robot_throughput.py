"""Robot throughput: robot-steps per second of batched, jitted episodes.

One robot-step is 100 ms of simulated time for one robot: 10 sonars (the paper's), the
collision test, the kinematics, and a 3-neuron CTRNN controller sub-stepped at h/tau = 0.05
(tau = 0.5 s: 4 Euler sub-steps). Batches: 126 (one DE generation, 18 controllers x the 7
crossroad mazes) and 4096 (robots spread over the 7 crossroads); and 4096 robots in a generated
30 x 30-cell corridor maze; and 4096 robots in a world that is not a grid (a 12 x 12-cell
corridor maze stretched by sqrt(2) / 1.4, so that its walls share no lattice step: the engine's
segment path).
Prints one JSON line; compile time is measured apart from run time.

    python benchmarks/robot_throughput.py [--steps 200] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import time

import jax
import jax.numpy as jnp
import numpy as np

from mbn.control.ctrnn import ctrnn_controller, initial_state, substeps_for
from mbn.networks.ctrnn import make_ctrnn
from mbn.world.engine import compile_mazes
from mbn.world.mazes.builtin import CROSSROAD_KINDS, crossroad
from mbn.world.mazes.generate import corridor_maze
from mbn.world.mazes.model import Maze
from mbn.world.rollout import RolloutConfig, junction_arrays, rollout


def measure(mazes: list[Maze], batch: int, steps: int, repeats: int) -> dict:
    world = compile_mazes(mazes)
    junctions = junction_arrays(mazes, world)
    rng = np.random.default_rng(0)
    net = make_ctrnn(
        rng.uniform(-10, 10, (batch, 3, 3)),
        rng.uniform(-10, 10, (batch, 3, 3)),
        0.5,
        dtype=np.float32,
    )
    maze_index = np.arange(batch) % len(mazes)
    poses = np.stack([mazes[m].starts[i % len(mazes[m].starts)] for i, m in enumerate(maze_index)])
    controller = ctrnn_controller(dt=0.1, substeps=substeps_for(0.1, 0.5, 0.05))
    config = RolloutConfig(steps=steps)
    run = jax.jit(
        lambda state, p, m: rollout(world, controller, state, p, m, config, junctions=junctions)
    )
    args = (initial_state(net), jnp.asarray(poses, jnp.float32), jnp.asarray(maze_index))
    start = time.perf_counter()
    out = jax.block_until_ready(run(*args))
    compile_s = time.perf_counter() - start
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        out = jax.block_until_ready(run(*args))
        best = min(best, time.perf_counter() - start)
    return {
        "robot_steps_per_s": batch * steps / best,
        "compile_s": compile_s,
        "run_s": best,
        "stall_fraction": float(np.mean(out.stats.stall_fraction)),
    }


def non_grid_maze() -> Maze:
    """A 12 x 12-cell corridor maze stretched by sqrt(2) / 1.4: walls on no common step (the
    engine's segment path)."""
    base = corridor_maze(12, 12, seed=1, loops=0.1, starts=64)
    k = math.sqrt(2) / 1.4
    x0, x1, y0, y1 = base.bounds
    return Maze(
        "stretched",
        walls=base.walls * k,
        bounds=(x0 * k, x1 * k, y0 * k, y1 * k),
        starts=base.starts * np.array([k, k, 1.0]),
        outside_is_wall=True,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    crossroads = [crossroad(kind) for kind in CROSSROAD_KINDS]
    large = corridor_maze(30, 30, seed=0, loops=0.1, starts=64)
    figures: dict = {}
    compile_s: dict = {}
    for batch in (126, 4096):
        m = measure(crossroads, batch, args.steps, args.repeats)
        figures[str(batch)] = m["robot_steps_per_s"]
        compile_s[str(batch)] = m["compile_s"]
    big = measure([large], 4096, args.steps, args.repeats)
    stretched = non_grid_maze()
    assert compile_mazes([stretched]).mode == "segments"
    odd = measure([stretched], 4096, args.steps, args.repeats)
    result = {
        "benchmark": "robot_throughput",
        "unit": "robot-steps/s (100 ms steps, 10 sonars, 3-neuron CTRNN x 4 sub-steps, float32)",
        "num_steps": args.steps,
        "robot_steps_per_s": figures,
        "robot_steps_per_s_large_maze": big["robot_steps_per_s"],
        "large_over_crossroads": big["robot_steps_per_s"] / figures["4096"],
        "robot_steps_per_s_non_grid": odd["robot_steps_per_s"],
        "non_grid_over_crossroads": odd["robot_steps_per_s"] / figures["4096"],
        "compile_s": max(compile_s.values()),
        "compile_s_by_batch": compile_s
        | {"large_4096": big["compile_s"], "non_grid_4096": odd["compile_s"]},
        "machine": {
            "platform": platform.platform(),
            "processor": platform.processor() or platform.machine(),
            "cpus": os.cpu_count(),
            "device": str(jax.devices()[0]),
        },
        "versions": {"jax": jax.__version__, "numpy": np.__version__},
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
