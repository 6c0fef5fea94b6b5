"""Robot throughput: robot-steps per second of batched, jitted episodes.

One robot-step is 100 ms of simulated time for one robot: 10 sonars (the paper's), the
collision test, the kinematics, and a controller. The world cases use a 3-neuron CTRNN
sub-stepped at h/tau = 0.05 (tau = 0.5 s: 4 Euler sub-steps). Batches: 126 (one DE generation,
18 controllers x the 7 crossroad mazes) and 4096 (robots spread over the 7 crossroads); and 4096
robots in a generated 30 x 30-cell corridor maze; and 4096 robots in a world that is not a grid
(a 12 x 12-cell corridor maze stretched by sqrt(2) / 1.4, so that its walls share no lattice
step: the engine's segment path).

The workload cases (``workload``) run what the experiment runs, built from controller files the
way ``mbn evaluate`` and the test stage load them (``mbn.controllers.make_controller``): the
3-neuron follower at ``NETWORK_SUBSTEPS`` (20 sub-steps of 5 ms), the 21-neuron interpreter of a
follower with 3 programmable connections (6-neuron multipliers) running a program, and the whole
MBN (program module, interpreter and camera) in ``fig4``, which has tiles; batches 126 and 4096;
the sonars cast as far as the inputs read them (2 m, ``mbn.world.rollout.input_reach``), as the
experiment's rollouts cast them (the world cases cast the whole 5 m).
Beside them: the same 21-neuron interpreter simulated by its structure (``interpreter_blocks``:
the neurons beside a batch of multipliers, :mod:`mbn.networks.structured`), and the fully
programmable interpreter of the follower genome (its 12 connections, 75 neurons) simulated so
(``interpreter_full``); and as ``mbn run new-behaviours`` runs it (14 connections, multipliers at
tau/40, 80 sub-steps: ``interpreter_full_80``) beside the follower at 80 sub-steps
(``follower_80``). ``interpreter`` and ``mbn`` run the multipliers at the paper's tau/10 (20
sub-steps); ``interpreter_80`` and ``mbn_80`` as ``mbn reproduce`` runs them since
``[interpreter]`` (tau/40, 80 sub-steps).

Prints one JSON line; compile time is measured apart from run time.

    python benchmarks/robot_throughput.py [--steps 200] [--repeats 3] [--only workload|world]
        [--batches 126,4096] [--cases follower,interpreter,mbn] [--parts N]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import platform
import time
from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np

from mbn.control.ctrnn import ctrnn_controller, initial_state, substeps_for
from mbn.controllers import (
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    MBNControllerSpec,
    make_controller,
)
from mbn.networks.ctrnn import make_ctrnn
from mbn.networks.multiplier import load_default
from mbn.networks.programmable import (
    Connection,
    Programmable,
    build_interpreter,
    differing_connections,
)
from mbn.world.engine import CameraConfig, compile_mazes
from mbn.world.mazes.builtin import CROSSROAD_KINDS, builtin_maze, crossroad
from mbn.world.mazes.generate import corridor_maze
from mbn.world.mazes.model import Maze
from mbn.world.rollout import RolloutConfig, input_reach, junction_arrays, rollout
from mbn.world.sensors import NoiseConfig, SensorConfig


def measure(mazes: list[Maze], batch: int, steps: int, repeats: int) -> dict:
    """The world cases: ``batch`` random 3-neuron CTRNNs (genes in +-10) at 4 sub-steps."""
    rng = np.random.default_rng(0)
    net = make_ctrnn(
        rng.uniform(-10, 10, (batch, 3, 3)),
        rng.uniform(-10, 10, (batch, 3, 3)),
        0.5,
        dtype=np.float32,
    )
    plain = SimpleNamespace(
        controller=ctrnn_controller(dt=0.1, substeps=substeps_for(0.1, 0.5, 0.05)),
        initial_state=lambda n: initial_state(net),
        sensors=SensorConfig(),
        camera=None,
    )
    return measure_loaded(mazes, batch, steps, repeats, plain)


def measure_loaded(
    mazes: list[Maze], batch: int, steps: int, repeats: int, loaded, parts: int = 1
) -> dict:
    """Like :func:`measure` for a controller made from a spec (``make_controller``). With
    ``parts > 1`` the batch is run in that many equal parts at once (threads), as the experiment
    evaluates its DE populations (``mbn reproduce --threads``)."""
    world = compile_mazes(mazes)
    junctions = junction_arrays(mazes, world)
    maze_index = np.arange(batch) % len(mazes)
    poses = np.stack([mazes[m].starts[i % len(mazes[m].starts)] for i, m in enumerate(maze_index)])
    # the sonars cast as far as the inputs read them, as the experiment's rollouts do
    reach = input_reach(loaded.sensors, NoiseConfig())
    config = RolloutConfig(
        steps=steps, sensors=loaded.sensors, camera=loaded.camera, sonar_reach=reach
    )
    run = jax.jit(
        lambda state, p, m: rollout(
            world, loaded.controller, state, p, m, config, junctions=junctions
        )
    )
    size = batch // parts
    args = (loaded.initial_state(size), jnp.asarray(poses[:size], jnp.float32))
    index = [jnp.asarray(maze_index[k * size : (k + 1) * size]) for k in range(parts)]
    pool = ThreadPoolExecutor(parts)

    def once() -> list:
        return [
            f.result()
            for f in [pool.submit(lambda m: jax.block_until_ready(run(*args, m)), m) for m in index]
        ]

    start = time.perf_counter()
    out = once()
    compile_s = time.perf_counter() - start
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        out = once()
        best = min(best, time.perf_counter() - start)
    pool.shutdown()
    return {
        "robot_steps_per_s": size * parts * steps / best,
        "compile_s": compile_s,
        "run_s": best,
        "stall_fraction": float(np.mean([np.mean(o.stats.stall_fraction) for o in out])),
    }


def workload_specs() -> dict:
    """The experiment's three controllers, float32: a follower (genes in +-20, the evolution's
    bound), the interpreter of it with the 3 connections where a left-follower differs
    programmable (the paper's W_23, WE_21, WE_22), and an MBN with a program module and the
    camera the experiment trains it with (0.8 m)."""
    rng = np.random.default_rng(0)
    f32 = np.float32
    rf = make_ctrnn(rng.uniform(-20, 20, (3, 3)), rng.uniform(-20, 20, (3, 3)), 0.5, dtype=f32)
    W, WE = np.array(rf.W), np.array(rf.WE)
    W[1, 2] += 8.0
    WE[1, 0] -= 6.0
    WE[1, 1] += 5.0
    lf = make_ctrnn(W, WE, 0.5, dtype=f32)
    interp = build_interpreter(rf, differing_connections(rf, lf, margin=0.0), load_default(6))
    programs = {
        "right": np.asarray(interp.program_of(rf), float).tolist(),
        "left": np.asarray(interp.program_of(lf), float).tolist(),
    }
    im = InterpreterControllerSpec(interpreter=interp, programs=programs)
    # as `mbn reproduce` runs it ([interpreter]: tau/40, 80 sub-steps)
    interp_80 = build_interpreter(
        rf, differing_connections(rf, lf, margin=0.0), load_default(6), tau_ratio=0.025
    )
    # the programs depend on the bounds (RF's and LF's weights), not on the multipliers' tau
    im_80 = InterpreterControllerSpec(interpreter=interp_80, programs=programs, substeps=80)
    pm = make_ctrnn(
        rng.uniform(-10, 10, (3, 3)),
        rng.uniform(-10, 10, (3, 2)),
        0.5,
        bias=rng.uniform(-10, 10, 3),
        dtype=f32,
    )
    # every connection of the follower genome programmable (W 3 x 3, WE on the diagonal, in
    # +-20), simulated by its structure; and the paper's interpreter by its structure too
    genome = [Connection("W", i, j) for i in range(3) for j in range(3)]
    genome += [Connection("WE", k, k) for k in range(3)]
    full = build_interpreter(rf, [Programmable(c, -20.0, 20.0) for c in genome], load_default(6))
    full_spec = InterpreterControllerSpec(
        interpreter=full,
        programs={"right": np.asarray(full.program_of(rf), float).tolist()},
        simulation="blocks",
    )
    # as `mbn run new-behaviours` runs it: 14 connections (the genome's and the turning
    # neuron's two other inputs), multipliers at tau/40, 80 sub-steps; beside the follower at 80
    fast = build_interpreter(
        rf,
        [
            Programmable(c, -20.0, 20.0)
            for c in (*genome, Connection("WE", 1, 0), Connection("WE", 1, 2))
        ],
        load_default(6),
        tau_ratio=0.025,
    )
    fast_spec = InterpreterControllerSpec(
        interpreter=fast,
        programs={"right": np.asarray(fast.program_of(rf), float).tolist()},
        simulation="blocks",
        substeps=80,
    )
    mbn = MBNControllerSpec(
        interpreter_spec=im,
        program_module=pm,
        program_neurons=(0, 1, 2),
        camera=CameraConfig(range=0.8),
    )
    return {
        "follower": CTRNNControllerSpec(net=rf),
        "interpreter": im,
        "interpreter_blocks": dataclasses.replace(im, simulation="blocks"),
        "interpreter_full": full_spec,
        "follower_80": CTRNNControllerSpec(net=rf, substeps=80),
        "interpreter_full_80": fast_spec,
        "mbn": mbn,
        "interpreter_80": im_80,
        "mbn_80": dataclasses.replace(mbn, interpreter_spec=im_80),
        "neurons": int(interp.num_neurons),
        "full_neurons": int(full.num_neurons),
    }


def workload(
    steps: int,
    repeats: int,
    parts: int = 1,
    batches: tuple[int, ...] = (126, 4096),
    only: tuple[str, ...] | None = None,
) -> dict:
    """Robot-steps/s of the experiment's controllers (see the module's docstring) at each of
    ``batches``; with ``parts > 1`` also with each batch run in that many parts at once (keys
    ``..._parts``); ``only`` names the cases to run (default: all)."""
    specs = workload_specs()
    crossroads = [crossroad(kind) for kind in CROSSROAD_KINDS]
    fig4 = [builtin_maze("fig4")]
    out: dict = {
        "interpreter_neurons": specs["neurons"],
        "interpreter_full_neurons": specs["full_neurons"],
    }
    compile_s: dict = {}
    cases = (
        ("follower", crossroads),
        ("interpreter", crossroads),
        ("interpreter_blocks", crossroads),
        ("interpreter_full", crossroads),
        ("follower_80", crossroads),
        ("interpreter_full_80", crossroads),
        ("mbn", fig4),
        ("interpreter_80", crossroads),
        ("mbn_80", fig4),
    )
    unknown = set(only or ()) - {name for name, _ in cases}
    if unknown:
        raise SystemExit(
            f"--cases: unknown case(s) {sorted(unknown)}; known: {[n for n, _ in cases]}"
        )
    for name, mazes in cases:
        if only is not None and name not in only:
            continue
        left = ("interpreter", "interpreter_blocks", "interpreter_80")
        program = "left" if name in left else None
        loaded = make_controller(specs[name], program, check_stability=False)
        for batch in batches:
            m = measure_loaded(mazes, batch, steps, repeats, loaded)
            out[f"{name}_{batch}"] = m["robot_steps_per_s"]
            compile_s[f"{name}_{batch}"] = m["compile_s"]
            if parts > 1:
                m = measure_loaded(mazes, batch, steps, repeats, loaded, parts)
                out[f"{name}_{batch}_parts"] = m["robot_steps_per_s"]
    out["compile_s"] = compile_s
    out["parts"] = parts
    return out


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


def machine() -> dict:
    return {
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
        "device": str(jax.devices()[0]),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--only", choices=("workload", "world"), default=None, help="run one group of cases"
    )
    parser.add_argument(
        "--parts",
        type=int,
        default=len(os.sched_getaffinity(0)),
        help="also run each workload batch in this many parts at once (default: the cores)",
    )
    parser.add_argument(
        "--batches",
        default="126,4096",
        help="comma-separated batch sizes of the workload cases (default: 126,4096)",
    )
    parser.add_argument(
        "--cases",
        default=None,
        help="comma-separated workload cases to run (default: all), e.g. follower,interpreter,mbn",
    )
    args = parser.parse_args()
    try:
        batches = tuple(int(b) for b in args.batches.split(","))
    except ValueError:
        parser.error(f"--batches: not a comma-separated list of integers: {args.batches!r}")
    cases = None if args.cases is None else tuple(args.cases.split(","))
    if args.only == "workload":
        print(
            json.dumps(
                {
                    "benchmark": "robot_throughput",
                    "unit": "robot-steps/s (100 ms steps, 10 sonars, float32)",
                    "num_steps": args.steps,
                    "workload": workload(args.steps, args.repeats, args.parts, batches, cases),
                    "machine": machine(),
                    "versions": {"jax": jax.__version__, "numpy": np.__version__},
                }
            )
        )
        return
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
        "workload": {}
        if args.only == "world"
        else workload(args.steps, args.repeats, args.parts, batches, cases),
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
        "machine": machine(),
        "versions": {"jax": jax.__version__, "numpy": np.__version__},
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
