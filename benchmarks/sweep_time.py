"""A whole sweep, timed: ``mbn sweep`` over some seeds, batched in one process (``--batched``)
or one Ray task per seed, as a whole process into a fresh folder with its own empty compilation
cache (cold) unless ``--warm`` names a cache folder to keep.

Prints one JSON line: the sweep's wall time (the process, from start to end), the time the sweep
itself recorded (``sweep.json``), each seed's seconds and robot-steps (its ``timings.json``),
the robot-steps per second over the sweep, the device JAX ran on, and the versions.

    python benchmarks/sweep_time.py [--seeds 0-1] [--quick] [--ray] [--warm DIR] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-1")
    ap.add_argument("--quick", action="store_true", help="quick runs (mbn sweep --quick)")
    ap.add_argument("--ray", action="store_true", help="one Ray task per seed, not --batched")
    ap.add_argument("--warm", type=Path, default=None, help="compilation cache folder to use")
    ap.add_argument("--keep", type=Path, default=None, help="the sweep folder (default: temp)")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory(prefix="mbn-sweep-bench-") as tmp:
        out = args.keep or Path(tmp) / "sweep"
        cache = args.warm or Path(tmp) / "compile-cache"
        cmd = [sys.executable, "-m", "mbn", "sweep", "--seeds", args.seeds, "--out", str(out)]
        cmd += ["--quiet"] + (["--quick"] if args.quick else [])
        cmd += [] if args.ray else ["--batched"]
        env = {**os.environ, "MBN_COMPILE_CACHE": str(cache)}
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            sys.exit(f"sweep_time: the sweep failed: {proc.stderr.strip()[-2000:]}")
        sweep = json.loads((out / "sweep.json").read_text())
        seeds = {}
        steps = 0
        for s in sweep["settings"]["seeds"]:
            timings = json.loads((out / f"seed-{s}" / "timings.json").read_text())
            seeds[str(s)] = {
                "seconds": timings["total_seconds"],
                "robot_steps": timings["total_robot_steps"],
            }
            steps += int(timings["total_robot_steps"])
        import jax

        print(
            json.dumps(
                {
                    "benchmark": "sweep_time",
                    "command": " ".join(["mbn", *cmd[3:]]).replace(str(out), "DIR"),
                    "executor": sweep.get("executor"),
                    "cache": "warm" if args.warm else "cold",
                    "wall_s": round(wall, 1),
                    "sweep_s": sweep.get("seconds"),
                    "seeds": seeds,
                    "robot_steps": steps,
                    "robot_steps_per_s": round(steps / wall),
                    "device": str(jax.devices()[0].device_kind),
                    "backend": jax.default_backend(),
                    "machine": f"{platform.machine()}, {os.cpu_count()} cores",
                    "python": platform.python_version(),
                    "jax": jax.__version__,
                    "code": {
                        k: sweep.get("code", {}).get(k) for k in ("version", "commit", "dirty")
                    },
                }
            )
        )


if __name__ == "__main__":
    main()
