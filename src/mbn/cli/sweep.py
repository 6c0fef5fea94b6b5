"""``mbn sweep``: one reproduction per seed as a Ray task, resumable, and its report."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from mbn.cli.args import ALLOW_OTHER_CODE_HELP, positive_int
from mbn.errors import MbnInputError
from mbn.precision import ROBOT

__all__ = ["EPILOG", "add_commands", "seed_list"]

EPILOG = """\
  mbn sweep --seeds 0-9 --out runs/sweep        10 seeds on a local Ray, one per core
  mbn sweep --summarize --out runs/sweep        rebuild the sweep's report from its folder
"""

_SWEEP_EPILOG = """\
Each seed K runs `mbn reproduce --seed K` (or, with --experiment NAME, `mbn run NAME --seed
K`) into DIR/seed-K (a normal run folder: `mbn evaluate` loads its
controllers) as one Ray task asking for --cpus-per-run CPUs, its BLAS threads pinned to
that many (and XLA to one thread for one CPU). Without --address a local Ray is started with
one CPU per core of this machine; with one, the sweep joins that cluster (`ray start --head`
on one machine, `ray start --address HEAD:6379` on the others; DIR must be on a file system
every machine sees at the same path).

Run the same command again to continue: finished seeds are skipped, interrupted ones resume from
their checkpoints; a seed that crashed is reported (sweep.json) and the others finish. An --out
holding a sweep with other --seeds, --quick, --config or --experiment is refused.

Every experiment starts with the reproduction's stages (RF, the LF search, LF, ...): --reuse
DIR, another sweep's folder, lets seed K take those it shares with DIR/seed-K instead of
running them again (docs/reproduce.md).

A sweep can be made in installments (machines that keep nothing between sessions, several
clusters): --keep keeps what a summary reads of its finished seeds, --combine makes one sweep of
several installments and summarizes it (docs/sweep.md, Installments).

outputs in DIR: seed-K/ (one per seed), sweep.json (settings, each seed's state, the statistics),
sweep.md, sweep.html (self-contained), figures/

At the end (unless --quiet), a table of each stage's median and max seconds over the seeds and
its robot-steps per second over all of them (each seed's timings.json), and the wall time.

examples:
  mbn sweep --seeds 0-9 --out runs/sweep
  mbn sweep --seeds 0,2,5-7 --quick --out runs/q
  mbn sweep --seeds 0-4 --experiment new-behaviours --out runs/nb-sweep
  mbn sweep --seeds 0-19 --experiment programs-vs-dynamics --out runs/pvd
  mbn sweep --seeds 0-7 --experiment new-behaviours --out runs/nb --reuse runs/pvd
  mbn sweep --seeds 0-99 --out /shared/sweep --address head-node:6379
  mbn sweep --summarize --out runs/sweep
  mbn sweep --keep kept/part1 --out runs/sweep              keep its finished seeds, small
  mbn sweep --combine kept/part1 runs/sweep2 --out runs/all  one sweep of two installments
"""


def seed_list(text: str) -> tuple[int, ...]:
    """An argument type: the seeds of ``0-9``, ``3`` or ``0,2,5-7``."""
    from mbn.experiments.sweep.seeds import parse_seeds

    try:
        return parse_seeds(text)
    except MbnInputError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("--seeds ")) from None


def add_commands(sub: Any, parser_class: type[argparse.ArgumentParser]) -> None:
    """Add ``sweep`` to the ``mbn`` sub-parsers."""
    from mbn.experiments.registry import registered

    sw = sub.add_parser(
        "sweep",
        help="one reproduction per seed on Ray, and statistics over the seeds",
        description="Run `mbn reproduce` (or, with --experiment, another experiment) once per "
        "seed, each run a Ray task (local or on a cluster) or, with --batched, a thread of this "
        "process, resumable; then a report over the seeds: per test how many seeds meet its "
        "target, the spread of success rates, Wilson intervals, DE curves and the claims.",
        epilog=_SWEEP_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sw.add_argument(
        "--seeds",
        type=seed_list,
        default=None,
        metavar="SEEDS",
        help=(
            "the seeds: 0-9, 3 or 0,2,5-7 (at most 1000); required unless --summarize, --keep "
            "or --combine. A sweep continued in its --out may gain seeds, never lose one"
        ),
    )
    sw.add_argument("--out", type=Path, required=True, metavar="DIR", help="the sweep folder")
    names = ", ".join(n for n in registered() if n != "reproduce")
    sw.add_argument(
        "--experiment",
        default=None,
        metavar="NAME",
        help="the experiment each seed runs: reproduce (default, `mbn reproduce`), "
        f"{names} (`mbn run NAME`; programs-vs-dynamics compared over the seeds: "
        "docs/contest.md), or one of your own by its reference, package.module:ATTRIBUTE or "
        'path/to/file.py:ATTRIBUTE (docs/architecture.md, "Your own experiment")',
    )
    sw.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="FILE.toml",
        help="settings file for every run (as `mbn reproduce --config`)",
    )
    sw.add_argument("--quick", action="store_true", help="quick runs (as `mbn reproduce --quick`)")
    sw.add_argument(
        "--address",
        default=None,
        metavar="ADDR",
        help="join the Ray cluster at HOST:PORT (default: start a local Ray on this machine)",
    )
    sw.add_argument(
        "--cpus-per-run",
        type=positive_int,
        default=1,
        metavar="N",
        help="CPUs Ray gives each run: its BLAS threads and DE evaluation parts, and one XLA "
        "thread for 1 (default 1; docs/sweep.md, Threads)",
    )
    sw.add_argument(
        "--batched",
        action="store_true",
        help="run every seed in this process, side by side, their populations evaluated "
        "together in one call per generation (for a GPU; each seed's results are those of "
        "its run alone: docs/sweep.md, Batched); no Ray",
    )
    sw.add_argument(
        "--reuse",
        type=Path,
        default=None,
        metavar="DIR",
        help="another sweep's folder: seed K takes the stages its experiment shares with "
        "DIR/seed-K (same seed, settings and code) instead of running them again",
    )
    sw.add_argument(
        "--summarize",
        action="store_true",
        help="only rebuild sweep.json's statistics and the report from the folder (runs nothing)",
    )
    sw.add_argument(
        "--keep",
        type=Path,
        default=None,
        metavar="NEW",
        help="keep the finished seeds of the sweep in --out in a new folder NEW: what a summary "
        "reads (each seed's run.json, timings.json and results.json gzip-compressed, and "
        "sweep.json; a few tens of kB a seed), for a sweep made in installments (runs nothing)",
    )
    sw.add_argument(
        "--combine",
        type=Path,
        nargs="+",
        default=None,
        metavar="DIR",
        help="make --out (a new folder) one sweep of the finished seeds of these sweeps "
        "(installments, whole or kept: the same experiment and settings, their seeds disjoint), "
        "and summarize it (runs nothing; docs/sweep.md, Installments)",
    )
    sw.add_argument("--allow-other-code", action="store_true", help=ALLOW_OTHER_CODE_HELP)
    sw.add_argument(
        "--quiet",
        action="store_true",
        help="no progress table or table of stage times, only the summary line",
    )
    sw.set_defaults(func=run_sweep_command, precision=ROBOT)


def run_sweep_command(args: argparse.Namespace) -> int:
    from mbn.experiments.sweep.report import summarize_folder, summary_line
    from mbn.experiments.sweep.seeds import format_seeds
    from mbn.experiments.sweep.timings import print_sweep_timings

    modes = [f for f, on in (("--summarize", args.summarize), ("--keep", args.keep is not None),
                             ("--combine", args.combine is not None)) if on]  # fmt: skip
    if len(modes) > 1:
        raise MbnInputError(f"{modes[0]} and {modes[1]} do not go together")
    if modes and (
        args.seeds is not None
        or args.config is not None
        or args.quick
        or args.experiment is not None
        or args.reuse is not None
        or args.allow_other_code
        or args.batched
    ):
        raise MbnInputError(
            f"{modes[0]} reads the settings from the sweeps' sweep.json: it takes --out "
            "(and --quiet) alone"
        )
    if args.keep is not None:
        from mbn.experiments.sweep.combine import keep_sweep

        kept = keep_sweep(args.out, args.keep)
        print(f"kept seeds {format_seeds(kept)} of {args.out} in {args.keep}")
        return 0
    if args.summarize or args.combine is not None:
        if args.combine is not None:
            from mbn.experiments.sweep.combine import combine_sweeps

            data = combine_sweeps(args.combine, args.out)
        else:
            data = summarize_folder(args.out)
        if not args.quiet:
            seeds = [int(s) for s in data["settings"].get("seeds", [])]
            print_sweep_timings(args.out, seeds, data.get("seconds"))
        print(summary_line(data) + f"; report: {args.out / 'sweep.html'}")
        return 0
    if args.seeds is None:
        raise MbnInputError(
            "--seeds is required (e.g. --seeds 0-9), unless --summarize, --keep or --combine"
        )
    if args.batched and (args.address is not None or args.cpus_per_run != 1):
        flag = "--address" if args.address is not None else "--cpus-per-run"
        raise MbnInputError(f"--batched runs every seed in this process: it takes no {flag}")
    from mbn.config import read_toml
    from mbn.experiments.sweep.monitor import SweepMonitor
    from mbn.experiments.sweep.run import BatchedExecutor, RayExecutor, SweepSettings, run_sweep
    from mbn.experiments.sweep.specs import sweep_spec

    spec = sweep_spec(args.experiment)
    experiment = spec.load()
    document = read_toml(args.config) if args.config is not None else None
    config = experiment.config(quick=args.quick, document=document)
    settings = SweepSettings(tuple(args.seeds), config, spec.name)
    monitor = None
    if not args.quiet:
        monitor = SweepMonitor(
            args.out,
            settings.seeds,
            experiment.registry.names,
            live=sys.stdout.isatty(),
            stream=sys.stdout,
        )
    data = run_sweep(
        args.out,
        settings,
        (lambda: BatchedExecutor())
        if args.batched
        else (lambda: RayExecutor(args.address, args.cpus_per_run)),
        monitor=monitor,
        finish=summarize_folder,
        reuse=args.reuse,
        allow_other_code=args.allow_other_code,
        executor_name="batched" if args.batched else "ray",
    )
    if not args.quiet:
        print_sweep_timings(args.out, settings.seeds, data.get("seconds"))
    if data.get("skipped"):
        print(f"{len(data['skipped'])} of {len(settings.seeds)} seeds were finished before: kept")
    print(summary_line(data) + f"; report: {args.out / 'sweep.html'}")
    return 0
