"""A Ray task that stands in for a seed's run (``mbn.experiments.sweep.run.run_seed``): it
writes a finished seed folder without simulating and reports its worker as ``run_seed`` does, so
that a test can drive ``mbn sweep`` on a real local Ray in seconds. The Ray workers import it
from the repository's root (``PYTHONPATH``)."""

from __future__ import annotations

import os
import socket
import sys
from pathlib import Path
from typing import Any

from mbn.experiments.pipeline import RunDir
from mbn.experiments.sweep.run import THREAD_VARIABLES
from tests.experiments.sweep.conftest import fake_run


def fake_seed(out: str, seed: int, config: Any, resume: bool, *rest: Any) -> dict[str, Any]:
    folder = fake_run(Path(out), seed, config.to_dict(), {}, {}, {"claim A": True}, [0.0, 1.0])
    RunDir(folder).write_timings({"rf": 1.0 + seed}, {"rf": 1_000_000})
    worker = {
        "host": socket.gethostname(),
        "pid": os.getpid(),
        "jax_imported_before": "jax" in sys.modules,
        "env": {k: os.environ.get(k) for k in THREAD_VARIABLES},
    }
    return {"seed": seed, "state": "done", "error": None, "seconds": 1.0, "worker": worker}


def main(argv: list[str]) -> int:
    """``mbn ARGV`` with the sweep's Ray tasks made :func:`fake_seed` (Ray itself is real)."""
    import mbn.experiments.sweep.run as sweep_run
    from mbn.cli.main import main as mbn_main

    real = sweep_run.RayExecutor
    sweep_run.RayExecutor = lambda address, cpus: real(address, cpus, task=fake_seed)
    return mbn_main(argv)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
