"""``mbn run EXPERIMENT``: a registered experiment other than the paper's (``mbn reproduce``)."""

from __future__ import annotations

import argparse
import sys
import textwrap
from pathlib import Path
from typing import Any

from mbn.cli.args import (
    ALLOW_OTHER_CODE_HELP,
    REUSE_HELP,
    available_cores,
    int_in,
    reuse_source,
    seed,
)
from mbn.precision import ROBOT

__all__ = ["EPILOG", "add_commands", "experiment"]

EPILOG = """\
  mbn run new-behaviours --out runs/nb        new behaviours by programs alone
  mbn run noise --out runs/noise              what survives noise
  mbn run ablations --out runs/ablations      ablations of the program path
  mbn run programs-vs-dynamics --out runs/pvd
                                              programs against dynamics (one seed)
  mbn run my_pkg.my_module:EXPERIMENT --out runs/mine
                                              an experiment of your own
"""

_EPILOG = """\
experiments:
{experiments}

Every DE generation is checkpointed in DIR/checkpoints: `mbn run EXPERIMENT --out DIR --resume`
continues where a run stopped. Settings as in `mbn reproduce` (`--print-config`, `--config`).
At the end, a table of each stage's seconds and robot-steps per second (DIR/timings.json).

examples:
  mbn run new-behaviours --out runs/nb                 a full run
  mbn run new-behaviours --quick --out /tmp/nb         smoke run
  mbn run new-behaviours --out runs/nb --resume        continue it
  mbn run new-behaviours --out runs/nb --reuse runs/pvd   RF, LF and IM taken from that run
  mbn run noise --out runs/noise                       the noise levels
  mbn run ablations --out runs/ablations               the ablations
  mbn run programs-vs-dynamics --out runs/pvd          programs against dynamics, one seed
"""


def experiment(name: str) -> Any:
    """The experiment ``name``, registered or a reference (``registry.find``)."""
    from mbn.experiments.registry import find

    return find(name).load()


def add_commands(sub: Any, parser_class: type[argparse.ArgumentParser]) -> None:
    """Add ``run`` to the ``mbn`` sub-parsers."""
    from mbn.experiments.registry import registered

    experiments = {k: r.help for k, r in registered().items()}
    width = max(map(len, experiments)) + 4
    listing = "\n".join(
        textwrap.fill(
            f"  {k:<{width - 2}}{v}",
            width=96,
            subsequent_indent=" " * width,
            break_on_hyphens=False,
        )
        for k, v in experiments.items()
    )
    cmd = sub.add_parser(
        "run",
        help=f"a registered experiment ({', '.join(experiments)}), or one of your own by its "
        "reference (package.module:ATTRIBUTE)",
        description="Run a registered experiment, stage by stage, checkpointed and resumable.",
        epilog=_EPILOG.format(experiments=listing),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    cmd.add_argument(
        "experiment",
        metavar="EXPERIMENT",
        help="a registered experiment's name (below), or the reference of one of your own: "
        "package.module:ATTRIBUTE or path/to/file.py:ATTRIBUTE (an "
        "mbn.experiments.pipeline.experiment.Experiment)",
    )
    cmd.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output folder (default runs/EXPERIMENT); refused if it holds another run, unless "
        "--resume or --force",
    )
    cmd.add_argument("--seed", type=seed, default=0, help="random seed (default 0)")
    cmd.add_argument(
        "--config", type=Path, default=None, metavar="FILE.toml", help="settings file (TOML)"
    )
    cmd.add_argument(
        "--print-config", action="store_true", help="print the effective config and exit"
    )
    cmd.add_argument("--quick", action="store_true", help="smoke run with tiny budgets")
    cmd.add_argument(
        "--resume", action="store_true", help="continue the run in --out where it stopped"
    )
    cmd.add_argument("--force", action="store_true", help="discard the run in --out and start anew")
    cmd.add_argument(
        "--reuse",
        type=Path,
        default=None,
        metavar="DIR",
        help=REUSE_HELP,
    )
    cmd.add_argument("--allow-other-code", action="store_true", help=ALLOW_OTHER_CODE_HELP)
    cmd.add_argument(
        "--quiet", action="store_true", help="no progress bars, stage lines or table of times"
    )
    cmd.add_argument(
        "--threads",
        type=int_in(1, 256),
        default=available_cores(),
        metavar="N",
        help=f"threads evaluating each DE population's two parts (default {available_cores()})",
    )
    cmd.set_defaults(func=run, precision=ROBOT)


def run(args: argparse.Namespace) -> int:
    from mbn.config import read_toml
    from mbn.experiments.pipeline.rundir import RunDir
    from mbn.experiments.pipeline.runner import run_experiment
    from mbn.experiments.pipeline.timings import print_run_timings

    exp = experiment(args.experiment)
    document = read_toml(args.config) if args.config is not None else None
    config = exp.config(quick=args.quick, document=document)
    if args.print_config:
        sys.stdout.write(config.to_toml(f"mbn run {args.experiment}: the effective config"))
        return 0
    out = args.out if args.out is not None else Path("runs") / exp.name
    run_experiment(
        exp,
        out,
        seed=args.seed,
        config=config,
        resume=args.resume,
        force=args.force,
        progress=not args.quiet and sys.stderr.isatty(),
        log=(lambda _m: None) if args.quiet else print,
        workers=args.threads,
        reuse=reuse_source(args.reuse, exp),
        allow_other_code=args.allow_other_code,
    )
    if not args.quiet:
        print_run_timings(RunDir(out))
        print(f"results: {out / 'results.json'}")
    return 0
