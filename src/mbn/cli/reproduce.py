"""``mbn reproduce``: the paper's whole experiment and its report."""

from __future__ import annotations

import argparse
import sys
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

__all__ = ["EPILOG", "add_commands", "effective_config"]

EPILOG = """\
  mbn reproduce --out runs/full                the paper's whole experiment and its report
  mbn reproduce --quick --out runs/quick       a smoke run of every stage
"""

_REPRODUCE_EPILOG = """\
stages: multiplier, rf, lf_search, lf, im, pm, tests, generalization, then results.json and the
report.
Every DE generation is checkpointed in DIR/checkpoints: after an interruption (Ctrl-C, kill -9,
a power cut) `mbn reproduce --out DIR --resume` continues where the run stopped and ends with the
same results.json as an uninterrupted run.

settings: every number a run depends on has a default (the paper's, or a documented deviation);
`--print-config` prints them all as TOML, with unit, range and source. Write any subset of them
into a file and pass it with `--config FILE.toml` (e.g. `[rf]` `generations = 100`). The
effective config is recorded in run.json and results.json; --resume refuses another one.

outputs in DIR: results.json, report.md, report.html (self-contained), controllers/ (rf.json,
lf.json, im.json, mbn.json, multiplier.json: try them with `mbn evaluate`), figures/,
timings.json (seconds and robot-steps per stage: the table printed at the end), stages/,
records/, checkpoints/, run.json

how long it takes: README, Set-up.

examples:
  mbn reproduce                                full run into runs/reproduce
  mbn reproduce --quick --out /tmp/q           smoke run
  mbn reproduce --out runs/s2 --seed 2         another seed
  mbn reproduce --out runs/s2 --seed 2 --resume    continue it after an interruption
  mbn reproduce --print-config > my.toml       every setting, to edit
  mbn reproduce --config my.toml --out runs/mine
"""


def add_commands(sub: Any, parser_class: type[argparse.ArgumentParser]) -> None:
    """Add ``reproduce`` to the ``mbn`` sub-parsers."""
    rep = sub.add_parser(
        "reproduce",
        help="the paper's whole experiment: evolve, build, test, report",
        description="Reproduce Montone, Donnarumma & Prevete (2011) end to end: the multiplier, "
        "the right- and left-follower evolved by DE (on maze episodes by default; the paper's "
        "crossroads with docs/configs/paper.toml), the interpreter built from them, the program "
        "module evolved with it, the paper's tests (plus jittered starts, a held-out maze and "
        "the published weights), every controller judged in generated mazes, and a report with a "
        "claims table.",
        epilog=_REPRODUCE_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    rep.add_argument(
        "--out",
        type=Path,
        default=Path("runs/reproduce"),
        help="output folder (default runs/reproduce); refused if it holds another run, unless "
        "--resume or --force",
    )
    rep.add_argument("--seed", type=seed, default=0, help="random seed (default 0)")
    rep.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="FILE.toml",
        help="settings file (TOML): any subset of the settings --print-config shows",
    )
    rep.add_argument(
        "--print-config",
        action="store_true",
        help="print the full effective config as TOML and exit (runs nothing)",
    )
    rep.add_argument(
        "--quick",
        action="store_true",
        help="smoke run: every stage and output with tiny budgets (not the paper's figures)",
    )
    rep.add_argument(
        "--retrain",
        action="store_true",
        help="train the multiplier again instead of using the shipped one (adds minutes); "
        "the same as [multiplier] retrain = true",
    )
    rep.add_argument(
        "--resume", action="store_true", help="continue the run in --out where it stopped"
    )
    rep.add_argument("--force", action="store_true", help="discard the run in --out and start anew")
    rep.add_argument("--reuse", type=Path, default=None, metavar="DIR", help=REUSE_HELP)
    rep.add_argument("--allow-other-code", action="store_true", help=ALLOW_OTHER_CODE_HELP)
    rep.add_argument(
        "--quiet", action="store_true", help="no progress bars, stage lines or table of times"
    )
    rep.add_argument(
        "--threads",
        type=int_in(1, 256),
        default=available_cores(),
        metavar="N",
        help="threads evaluating each DE population's two parts (2 evaluates them at once; "
        f"default: the cores this process may use, here {available_cores()}); the results do "
        "not depend on it",
    )
    # The stages run in the config's precision ([run] precision); this is the default's.
    rep.set_defaults(func=run_reproduce, precision=ROBOT)


def effective_config(config_file: Path | None, quick: bool, retrain: bool = False) -> Any:
    """The effective config of a reproduction: the defaults, then the ``--quick`` preset, then
    the settings file, then ``--retrain``."""
    from mbn.config import read_toml
    from mbn.experiments.pipeline.runner import replace_section
    from mbn.experiments.reproduce import REPRODUCE
    from mbn.experiments.stages.multiplier import MultiplierSettings

    document = read_toml(config_file) if config_file is not None else None
    config = REPRODUCE.config(quick=quick, document=document)
    if retrain:
        config = replace_section(config, config.get(MultiplierSettings).replace(retrain=True))
    return config


def run_reproduce(args: argparse.Namespace) -> int:
    from mbn.experiments.pipeline.rundir import RunDir
    from mbn.experiments.pipeline.runner import run_experiment
    from mbn.experiments.pipeline.timings import print_run_timings
    from mbn.experiments.reproduce import REPRODUCE

    config = effective_config(args.config, args.quick, args.retrain)
    if args.print_config:
        header = (
            "mbn reproduce: the effective config"
            + (f" (defaults, --quick, {args.config})" if args.quick and args.config else "")
            + (f" (defaults and {args.config})" if args.config and not args.quick else "")
            + (" (defaults and --quick)" if args.quick and not args.config else "")
            + "\nEach setting: what it is; unit; valid range; where its default comes from."
        )
        sys.stdout.write(config.to_toml(header))
        return 0
    results = run_experiment(
        REPRODUCE,
        args.out,
        seed=args.seed,
        config=config,
        resume=args.resume,
        force=args.force,
        progress=not args.quiet and sys.stderr.isatty(),
        log=(lambda _m: None) if args.quiet else print,
        workers=args.threads,
        reuse=reuse_source(args.reuse, REPRODUCE),
        allow_other_code=args.allow_other_code,
    )
    if not args.quiet:
        print_run_timings(RunDir(args.out))
        held = sum(c["pass"] for c in results["claims"])
        print(f"{held} of {len(results['claims'])} claims hold; report: {args.out / 'report.html'}")
    return 0
