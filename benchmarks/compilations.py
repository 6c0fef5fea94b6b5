"""Compilations: how many XLA programs an ``mbn`` command compiles, and where they come from.

Runs one ``mbn`` command in this process (default ``reproduce --quick --seed 0`` into a fresh
temporary folder) with JAX's persistent compilation cache off, so that every program is compiled
as on a fresh machine, and counts JAX's "Compiling" log lines: jitted functions and eager
operations alike (an eager ``jnp`` operation on a new shape compiles a program of its own). Each
compilation is charged to the innermost frame of ``mbn`` that asked for it, and the report lists
the sources with the most. Tracing, lowering and XLA's compilation are timed apart.

Prints one JSON line: the command, its wall time, the number of compilations, the seconds spent
tracing, lowering and compiling, and the top sources (``--top``).

    python benchmarks/compilations.py [--top 15] [-- reproduce --quick --seed 3]
"""

from __future__ import annotations

import argparse
import collections
import json
import logging
import os
import platform
import re
import sys
import tempfile
import time
import traceback
from pathlib import Path

COMPILING = re.compile(r"^Compiling (?:jit\()?([^ )]+)\)?")
TIMED = re.compile(
    r"^Finished (tracing|jaxpr to MLIR module conversion|XLA compilation)[^\d]*([\d.]+) sec"
)
PHASES = {
    "tracing": "trace_s",
    "jaxpr to MLIR module conversion": "lower_s",
    "XLA compilation": "compile_s",
}


def _origin(depth: int = 3) -> str:
    """The innermost ``depth`` frames in ``mbn`` (not this script) of the current stack, the
    innermost first: where an eager operation ran, and who asked for it."""
    frames = []
    for frame in reversed(traceback.extract_stack()[:-3]):
        name = frame.filename.replace(os.sep, "/")
        if "/mbn/" in name and "/benchmarks/" not in name:
            frames.append(f"{name.split('/mbn/', 1)[1]}:{frame.lineno} ({frame.name})")
            if len(frames) == depth:
                break
    return " < ".join(frames) or "(outside mbn)"


class Counter(logging.Handler):
    def __init__(self, depth: int = 1) -> None:
        super().__init__(logging.DEBUG)
        self.depth = depth
        self.count = 0
        self.by_name: collections.Counter[str] = collections.Counter()
        self.by_origin: collections.Counter[str] = collections.Counter()
        self.by_both: collections.Counter[str] = collections.Counter()
        self.seconds: collections.Counter[str] = collections.Counter()

    def emit(self, record: logging.LogRecord) -> None:
        message = record.getMessage()
        m = COMPILING.match(message)
        if m:
            self.count += 1
            self.by_name[m.group(1)] += 1
            origin = _origin(self.depth)
            self.by_origin[origin] += 1
            self.by_both[f"{m.group(1)} @ {origin}"] += 1
            return
        t = TIMED.match(message)
        if t:
            self.seconds[PHASES[t.group(1)]] += float(t.group(2))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--top", type=int, default=15, help="sources listed (default 15)")
    parser.add_argument(
        "--depth", type=int, default=1, help="mbn frames named per source (default 1)"
    )
    parser.add_argument("command", nargs="*", help="the mbn command (after --)")
    args = parser.parse_args()
    command = args.command or ["reproduce", "--quick", "--seed", "0"]

    os.environ["MBN_COMPILE_CACHE"] = "off"
    os.environ.pop("JAX_COMPILATION_CACHE_DIR", None)
    import jax

    jax.config.update("jax_log_compiles", True)
    counter = Counter(args.depth)
    for name in ("jax._src.dispatch", "jax._src.interpreters.pxla", "jax._src.compiler"):
        logger = logging.getLogger(name)
        logger.addHandler(counter)
        logger.setLevel(logging.DEBUG)
        logger.propagate = False

    from mbn.cli.main import main as mbn_main

    with tempfile.TemporaryDirectory(prefix="mbn-compilations-") as tmp:
        full = list(command)
        if full[0] in ("reproduce", "run") and "--out" not in full:
            full += ["--out", str(Path(tmp) / "run")]
        if "--quiet" not in full:
            full.append("--quiet")
        start = time.perf_counter()
        status = mbn_main(full)
        if status:
            sys.exit(status)
        wall = time.perf_counter() - start

    result = {
        "benchmark": "compilations",
        "command": "mbn " + " ".join(command),
        "wall_s": round(wall, 2),
        "compilations": counter.count,
        **{k: round(v, 2) for k, v in sorted(counter.seconds.items())},
        "by_origin": dict(counter.by_origin.most_common(args.top)),
        "by_name": dict(counter.by_name.most_common(args.top)),
        "by_name_and_origin": dict(counter.by_both.most_common(args.top)),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores",
        "python": platform.python_version(),
        "jax": jax.__version__,
        "backend": jax.default_backend(),
    }
    print(json.dumps(result))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
