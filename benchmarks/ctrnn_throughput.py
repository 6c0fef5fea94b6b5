"""CTRNN throughput: network-steps per second for 3- and 12-neuron networks at batch 1, 126, 4096.

One network-step is one integrator step of one network (one state vector). Prints one JSON line;
compile time is measured apart from run time (the first call compiles, later calls are timed).

    python benchmarks/ctrnn_throughput.py [--steps 2000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import jax
import jax.numpy as jnp
import numpy as np

from mbn.networks.ctrnn import make_ctrnn, simulate


def measure(num_neurons: int, batch: int, num_steps: int, repeats: int, method: str) -> dict:
    rng = np.random.default_rng(0)
    net = make_ctrnn(
        rng.uniform(-5, 5, (num_neurons, num_neurons)),
        rng.uniform(-5, 5, (num_neurons, 3)),
        0.5,
        dtype=np.float32,
    )
    y0 = jnp.zeros((batch, num_neurons), jnp.float32)
    inputs = jax.random.uniform(jax.random.key(0), (num_steps, batch, 3), jnp.float32)
    start = time.perf_counter()
    jax.block_until_ready(simulate(net, y0, inputs, 0.01, method=method, record=False)[0])
    compile_s = time.perf_counter() - start
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(simulate(net, y0, inputs, 0.01, method=method, record=False)[0])
        best = min(best, time.perf_counter() - start)
    return {"steps_per_s": batch * num_steps / best, "compile_s": compile_s, "run_s": best}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    result: dict = {
        "benchmark": "ctrnn_throughput",
        "unit": "network-steps/s (float32, inputs held per step, no trajectory recorded)",
        "num_steps": args.steps,
    }
    for method in ("euler", "rk4"):
        figures: dict = {}
        compile_s: dict = {}
        for n in (3, 12):
            for batch in (1, 126, 4096):
                m = measure(n, batch, args.steps, args.repeats, method)
                figures.setdefault(str(n), {})[str(batch)] = round(m["steps_per_s"])
                compile_s.setdefault(str(n), {})[str(batch)] = round(m["compile_s"], 3)
        result[f"network_steps_per_s_{method}"] = figures
        result[f"compile_s_{method}"] = compile_s
    result["machine"] = {
        "cpu_count": os.cpu_count(),
        "processor": platform.processor() or platform.machine(),
        "python": platform.python_version(),
        "jax": jax.__version__,
        "backend": jax.default_backend(),
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
