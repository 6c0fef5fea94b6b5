"""Judging in generated mazes: a run's controllers judged as its ``generalization`` stage judges
them (the first N mazes of the train, validation and test splits of their family in one batch,
every start mark once, under the longest of the mazes' time limits), the whole rollout against
trials that stop once judged (:mod:`mbn.world.judged`).

For each controller: both ways twice in one process (the first call compiles, the second runs
what is compiled), the robot-steps each ran, and whether every verdict is the same. Prints one
JSON line. (The persistent compilation cache is the command line's; it is not on here, so the
first call compiles every program.)

    python benchmarks/judging.py --run runs/nb-s0/seed-0 [--mazes 100] [--only NAME,...]
        [--shrink 4]

The run folder is one seed's (``mbn run new-behaviours --seed 0 --out runs/nb-s0`` makes
``runs/nb-s0``; a sweep's seed folder ``seed-K`` likewise), with its ``generalization`` stage.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import jax
import numpy as np

from mbn import precision
from mbn.controllers import make_controller, read_controller_spec
from mbn.experiments.stages.common import tile_family
from mbn.experiments.trials import TrialGroup, TrialSpec, route_seconds, run_trial_groups
from mbn.world import judged as judged_module
from mbn.world.mazes import families
from mbn.world.rollout import robot_steps


def _judged_controllers(run: Path) -> dict[str, dict]:
    path = run / "stages" / "generalization.json"
    if not path.is_file():
        sys.exit(f"{path}: no generalization stage in this run folder (a seed's folder)")
    data = json.loads(path.read_text())
    result = data.get("result", data)
    return result["controllers"]


def _one(run: Path, name: str, rec: dict, mazes_per_split: int) -> dict:
    spec = read_controller_spec(run / rec["file"])
    loaded = make_controller(spec, rec.get("program"), check_stability=False)
    behavior = rec["behavior"]
    tile_rules = tuple(loaded.tile_rules or ("right", "left"))
    family = rec.get("family") or (tile_family(tile_rules) if behavior == "tiles" else "grid")
    initial = (loaded.initial_rule or "right") if behavior == "tiles" else "right"
    trial = TrialSpec(behavior=behavior, initial=initial, tile_rules=tile_rules)
    mazes = [
        families.generate(family, s)
        for split in ("train", "validation", "test")
        for s in families.split_seeds(split, 0, mazes_per_split - 1, family)
    ]
    seconds = max(route_seconds(m, trial) for m in mazes)
    groups = [TrialGroup(m.name, i, trial, loaded.initial_state) for i, m in enumerate(mazes)]
    camera = loaded.camera
    if camera is None and behavior == "tiles":
        from mbn.world.engine import CameraConfig

        camera = CameraConfig()
    out: dict = {"family": family, "mazes": len(mazes), "seconds": seconds}
    verdicts = {}
    for mode in ("whole", "until_judged"):
        times, steps = [], []
        for _ in range(2):
            before, t0 = robot_steps(), time.perf_counter()
            with precision.scope(precision.ROBOT):
                got, _, _, _ = run_trial_groups(
                    mazes,
                    groups,
                    loaded.controller,
                    seconds=seconds,
                    dt=loaded.dt,
                    sensors=loaded.sensors,
                    camera=camera,
                    until_judged=mode == "until_judged",
                )
            times.append(time.perf_counter() - t0)
            steps.append(robot_steps() - before)
        verdicts[mode] = got
        out[mode] = {
            "first_s": round(times[0], 2),
            "run_s": round(times[1], 2),
            "compile_s": round(times[0] - times[1], 2),
            "robot_steps": steps[1],
        }
    out["trials"] = int(sum(v["success"].shape[0] for v in verdicts["whole"].values()))
    out["same_verdicts"] = all(
        np.array_equal(a[k], verdicts["until_judged"][g][k])
        for g, a in verdicts["whole"].items()
        for k in a
    )
    out["speedup_run"] = round(out["whole"]["run_s"] / out["until_judged"]["run_s"], 2)
    out["speedup_first"] = round(out["whole"]["first_s"] / out["until_judged"]["first_s"], 2)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, required=True, help="a seed's run folder")
    ap.add_argument("--mazes", type=int, default=100, help="mazes of each split (default 100)")
    ap.add_argument("--only", default=None, help="judged controllers, comma-separated")
    ap.add_argument("--shrink", type=int, default=judged_module.SHRINK)
    args = ap.parse_args()
    judged_module.SHRINK = args.shrink
    controllers = _judged_controllers(args.run)
    names = args.only.split(",") if args.only else list(controllers)
    unknown = [n for n in names if n not in controllers]
    if unknown:
        known = ", ".join(controllers)
        sys.exit(f"--only: not judged in this run: {', '.join(unknown)} (judged: {known})")
    results = {n: _one(args.run, n, controllers[n], args.mazes) for n in names}
    print(
        json.dumps(
            {
                "benchmark": "judging",
                "run": str(args.run),
                "mazes_per_split": args.mazes,
                "chunk_steps": judged_module.CHUNK_STEPS,
                "shrink": judged_module.SHRINK,
                "floor": judged_module.FLOOR,
                "controllers": results,
                "machine": {
                    "cpus": os.cpu_count(),
                    "python": platform.python_version(),
                    "jax": jax.__version__,
                    "platform": platform.platform(),
                },
            }
        )
    )


if __name__ == "__main__":
    main()
