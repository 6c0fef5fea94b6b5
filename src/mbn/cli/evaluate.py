"""``mbn evaluate``: the paper's test protocol on a controller file (float32, as the robot
experiments: :mod:`mbn.precision`)."""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np

from mbn.cli.args import int_in, number_in, seed
from mbn.errors import MbnInputError
from mbn.io import json_text
from mbn.precision import ROBOT

__all__ = ["EPILOG", "add_commands"]

EPILOG = """\
  mbn evaluate --controller rf.json --maze fig4 --behavior right --repeats 3 --json
"""

_EVALUATE_EPILOG = """\
controller: a controller file (docs/controllers.md): kind mbn.controller.ctrnn, \
mbn.controller.interpreter or mbn.controller.mbn, or a kind an installed package registers \
(docs/architecture.md, "Adding a controller kind")
maze: a built-in name (see `mbn mazes`) or a .maze, .toml or Player/Stage .world file with start
marks (and tiles for --behavior tiles); a .toml or .world maze is judged when it is a grid of
corridors: closed, every corridor one width and one cell wide, blocks of any size, anywhere within
10 km of the origin (positions stay the world's; docs/mazes.md, "Which mazes can be judged")

examples:
  mbn evaluate --controller rf.json --maze fig4 --behavior right
  mbn evaluate --controller im.json --maze fig4 --behavior left --repeats 5 --json
  mbn evaluate --controller mbn.json --maze fig4 --behavior tiles --initial right --json
  mbn evaluate --controller rf.json --maze grid/validation:0-9 --behavior right

a split (FAMILY/SPLIT, docs/generalization.md) runs every maze's trials in one batch under one
time limit (the longest of the mazes' own) and prints one line per maze and the pooled figures;
--json: {"split", "mazes": [{"maze", ...the fields above}], "pooled", "mazes_at_95",
"fraction_of_mazes_at_95", "seconds"}.

--json prints one object: {"trials", "successes", "success_rate", "timed_out", "junctions",
"correct_junctions", "mean_stall_fraction", "seconds"}; timed_out counts the trials that ended
before their last judged junction with no wrong exit and no stall failure (the time limit ended
them, not the controller): raise --seconds. With --noise, "noise" holds the levels it ran under.

noise: every channel off by default; the same --seed gives the same noise (docs/noise.md):
  mbn evaluate --controller mbn.json --maze fig4 --behavior tiles --repeats 20 \
      --noise sonar_std=0.02,sonar_dropout=0.01,wheel_std=0.05,camera_miss=0.05

time limit: by default derived from the maze: 1.5 x the time, at 0.3 m/s (the evolved followers'
typical speed), of the longest route from a start mark through the judged junctions by the rule
in force (for tiles: following the tiles), rounded up to 10 s, at least 60 s; fig4 gives 90 s.
"""


def add_commands(sub: Any, parser_class: type[argparse.ArgumentParser]) -> None:
    """Add the experiment commands to the ``mbn`` sub-parsers (``parser_class`` is the class
    the sub-parsers use; as every command group takes)."""
    from mbn.experiments.trials import BEHAVIORS

    ev = sub.add_parser(
        "evaluate",
        help="test a controller file in a maze (the paper's protocol)",
        description="Run a controller from every start mark of a maze, --repeats times each (the "
        "first from the mark exactly, the others jittered: lateral +-0.15 m, along the corridor "
        "+-0.3 m, heading +-10 degrees). A trial succeeds when the robot's first --junctions "
        "junction passes each take the exit of the rule in force (right, left, or for 'tiles' "
        "the rule of the last tile driven over: one colour right, two colours left) within "
        "--seconds, stalled in at most 2 % of its steps. Prints one line per start mark and a "
        "total, or with --json one object.",
        epilog=_EVALUATE_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ev.add_argument("--controller", type=Path, required=True, help="controller JSON file")
    ev.add_argument(
        "--maze",
        required=True,
        help="built-in name, maze file, generated maze (FAMILY:SEED) or a family's split "
        "(FAMILY/SPLIT, FAMILY/SPLIT:A-B: every maze, one line each)",
    )
    ev.add_argument(
        "--behavior",
        type=_behavior,
        required=True,
        metavar="{" + ",".join(BEHAVIORS) + ",ORDER}",
        help="the rule a trial is judged by: a name, or any priority order of the exits right, "
        "straight and left (e.g. SRL, straight>right>left); 'tiles' needs a controller that "
        "reads the tiles (an mbn controller, or a CTRNN with tile_rules) and a maze with tiles",
    )
    ev.add_argument(
        "--initial",
        type=_initial,
        default=None,
        metavar="{right,left,...,none}",
        help="rule before the first tile, for --behavior tiles (default: the rule the mbn file "
        "starts with, its 'initial'; right for a file without one); none: judge only the "
        "junctions after the first tile",
    )
    ev.add_argument(
        "--program",
        type=_program_name,
        default=None,
        metavar="NAME",
        help="program of an interpreter file (default: the one named by --behavior, e.g. right, "
        "left, straight-right); for an mbn file, run its interpreter alone with this stored "
        "program",
    )
    ev.add_argument(
        "--repeats",
        type=int_in(1, 10_000),
        default=1,
        help="trials per start mark (default 1)",
    )
    ev.add_argument(
        "--junctions",
        type=int_in(1, 32),
        default=3,
        help="consecutive junctions judged (default 3, the paper's)",
    )
    ev.add_argument(
        "--seconds",
        type=number_in(36_000, " s"),
        default=None,
        help="time limit of a trial in seconds (default: derived from the maze, see below; "
        "fig4: 90)",
    )
    ev.add_argument(
        "--seed", type=seed, default=0, help="seed of the jitter and of the noise (default 0)"
    )
    ev.add_argument(
        "--noise",
        type=_noise,
        metavar="KEY=VALUE,...|FILE.toml",
        default=None,
        help="run under noise (default none): e.g. sonar_std=0.02,sonar_dropout=0.01,"
        "wheel_std=0.05,camera_miss=0.05, or a settings file's [noise] table; keys: "
        "sonar_std, sonar_dropout, camera_miss, camera_false, wheel_std, v_std, w_std, "
        "neuron_std, program_std, sonar_cone, and per episode corridor_scale, wheel_bias "
        "(docs/noise.md)",
    )
    ev.add_argument(
        "--allow-unstable",
        action="store_true",
        help="run a controller whose network step is beyond its integrator's stability limit "
        "(refused by default: e.g. the paper's published weights at 20 substeps)",
    )
    ev.add_argument("--json", action="store_true", help="print one JSON object")
    ev.set_defaults(func=_cmd_evaluate, precision=ROBOT)


def _noise(text: str) -> str:
    """``--noise``: kept as written for :func:`mbn.world.sensors.parse_noise`, which reads it;
    a key given twice is refused here (the last would silently win)."""
    if text.endswith(".toml"):  # a TOML table holds each key once (its parser refuses a repeat)
        return text
    seen: set[str] = set()
    for item in text.split(","):
        key, sep, _ = item.partition("=")
        key = key.strip()
        if sep and key in seen:
            shown = key if len(key) <= 40 else key[:40] + "..."
            raise argparse.ArgumentTypeError(f"{shown} is given twice: give each key once")
        seen.add(key)
    return text


def _program_name(text: str) -> str:
    """``--program``: the name of a program stored in the file (not empty)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(
            f"expected the name of a program stored in the controller file, got {text!r}"
        )
    return text


def _initial(text: str) -> str:
    """``--initial``: 'none' or a rule (kept as its name)."""
    return "none" if text == "none" else _behavior(text)


def _behavior(text: str) -> str:
    """``--behavior``: 'tiles' or a rule (kept as its name)."""
    from mbn.world.rules import parse_rule

    if text == "tiles":
        return text
    try:
        return parse_rule(text).name
    except MbnInputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _program_for(args: argparse.Namespace, kind: str, reads_tiles: bool = False) -> str | None:
    """The program to run for this kind of file and these flags (or a one-line error);
    ``reads_tiles``: a file with tile rules (a CTRNN that reads the tiles itself, or a kind
    registered outside ``mbn`` whose spec has ``tile_rules``)."""
    from mbn.controllers import KIND_CTRNN, KIND_INTERPRETER, KIND_MBN

    path = args.controller
    if kind not in (KIND_CTRNN, KIND_INTERPRETER, KIND_MBN):  # a kind registered outside mbn
        if args.behavior == "tiles" and not reads_tiles:
            raise MbnInputError(
                f"--behavior tiles needs a controller that reads the tiles; {path} is a {kind} "
                "controller without tile_rules"
            )
        return args.program  # None unless given: its runner refuses a program it has not
    if kind == KIND_CTRNN:
        if args.behavior == "tiles" and not reads_tiles:
            raise MbnInputError(
                f"--behavior tiles needs a controller that reads the tiles (an mbn controller, "
                f"or a CTRNN with tile_rules); {path} is a plain CTRNN controller ({kind})"
            )
        if args.program is not None:
            raise MbnInputError(
                f"--program is for interpreter and mbn controllers; {path} is a plain CTRNN "
                f"controller ({kind})"
            )
        return None
    if kind == KIND_INTERPRETER:
        if args.behavior == "tiles":
            raise MbnInputError(
                f"--behavior tiles needs an mbn controller (program module + interpreter); "
                f"{path} is an interpreter controller ({kind}): use --behavior right or left"
            )
        return str(args.program or args.behavior)
    if args.program is not None and args.behavior == "tiles":
        raise MbnInputError(
            "--program fixes the interpreter's program; --behavior tiles needs the program "
            "module to choose it (drop --program)"
        )
    program: str | None = args.program
    return program


_HEADINGS = ("E", "NE", "N", "NW", "W", "SW", "S", "SE")


#: Folded into the seed's key for the noise of `mbn evaluate`'s trials.
NOISE_STREAM = 7


def _noise_text(noise: Any) -> str:
    return ", ".join(f"{k}={v:g}" for k, v in noise.as_dict().items() if v > 0)


def _heading(theta: float) -> str:
    return _HEADINGS[round(theta / (math.pi / 4)) % 8]


def _cmd_evaluate(args: argparse.Namespace) -> int:
    import jax

    from mbn.controllers import (
        check_trial_length,
        kind_of,
        make_controller,
        read_controller_spec,
    )
    from mbn.experiments.trials import TrialSpec, route_seconds, run_loaded_trials, summary
    from mbn.world.mazes.gridify import as_grid_maze
    from mbn.world.mazes.load import load_mazes
    from mbn.world.sensors import NoiseConfig, parse_noise

    mazes, split = load_mazes(args.maze)
    mazes = [as_grid_maze(m) for m in mazes]  # TOML and Stage mazes on a lattice of corridors
    maze = mazes[0]
    controller_spec = read_controller_spec(args.controller)
    kind = kind_of(controller_spec)
    assert kind is not None  # a spec read from a file is of a registered kind
    # the rule each tile kind puts in force: the mbn file's (the paper's: right, left)
    tile_rules = getattr(controller_spec, "tile_rules", None) or ("right", "left")
    for each in mazes:
        TrialSpec(behavior=args.behavior, tile_rules=tile_rules).check_maze(each)
    noise = parse_noise(args.noise) if args.noise is not None else NoiseConfig()
    loaded = make_controller(
        controller_spec,
        _program_for(args, kind.name, getattr(controller_spec, "tile_rules", None) is not None),
        where=str(args.controller),
        check_stability=not args.allow_unstable,
        noise=noise,
    )
    initial = args.initial
    if initial is None:  # the rule the file starts with, else right
        initial = loaded.initial_rule or "right"
    spec = TrialSpec(
        behavior=args.behavior,
        initial=initial,
        repeats=args.repeats,
        junctions=args.junctions,
        seed=args.seed,
        tile_rules=tile_rules,
    )
    spec.check_maze(maze)
    if split is not None:
        return _evaluate_split(args, split, mazes, spec, loaded, noise)
    seconds = args.seconds if args.seconds is not None else route_seconds(maze, spec)
    # a bounded number of robot and network steps (a tiny dt or many substeps: hours)
    check_trial_length(loaded, seconds, str(args.controller), limit_name="--seconds")
    spec = dataclasses.replace(spec, seconds=seconds)
    # the seed becomes the noise's key here, once (the jitter draws from its own generator)
    key = jax.random.fold_in(jax.random.key(args.seed), NOISE_STREAM) if noise.enabled else None
    verdict, _, _ = run_loaded_trials(maze, spec, loaded, key)
    result = {**summary(verdict), "seconds": seconds}
    if noise.enabled:
        result["noise"] = noise.as_dict()
    if args.json:
        print(json_text(result))
        return 0
    what = loaded.kind + (f", program {loaded.program}" if loaded.program else "")
    print(
        f"{args.controller} ({what}) in maze {maze.name!r}: behavior {args.behavior}"
        + (f" (initial {initial})" if args.behavior == "tiles" else "")
        + f", {len(maze.starts)} start marks x {args.repeats}, {args.junctions} junctions, "
        f"{seconds:g} s"
        + ("" if args.seconds is not None else " (from the maze)")
        + (f", noise {_noise_text(noise)}" if noise.enabled else "")
    )
    success = np.asarray(verdict["success"]).reshape(len(maze.starts), args.repeats)
    timed_out = np.asarray(verdict["timed_out"]).reshape(len(maze.starts), args.repeats)
    correct = np.asarray(verdict["correct"]).reshape(len(maze.starts), args.repeats)
    judged = np.asarray(verdict["judged"]).reshape(len(maze.starts), args.repeats)
    width = len(str(len(maze.starts)))
    for m, (x, y, theta) in enumerate(np.asarray(maze.starts)):
        print(
            f"  start {m + 1:>{width}} at ({x:.2f}, {y:.2f}) facing {_heading(float(theta))}: "
            f"{int(success[m].sum())}/{args.repeats} successes, "
            + (f"{int(timed_out[m].sum())} timed out, " if timed_out[m].any() else "")
            + f"{int(correct[m].sum())}/{int(judged[m].sum())} correct junctions"
        )
    print(
        f"  total: {result['successes']}/{result['trials']} successes "
        f"({result['success_rate']:.1%}), {result['timed_out']} timed out"
        + (" (raise --seconds)" if result["timed_out"] else "")
        + ", "
        f"{result['correct_junctions']}/{result['junctions']} "
        f"correct junctions, mean stall fraction {result['mean_stall_fraction']:.4f}"
    )
    return 0


def _evaluate_split(
    args: argparse.Namespace, split: str, mazes: list[Any], spec: Any, loaded: Any, noise: Any
) -> int:
    """``mbn evaluate`` over a split of a maze family: every maze's trials in one rollout, one
    line per maze and the pooled figures."""
    import jax

    from mbn.controllers import check_trial_length
    from mbn.experiments.generalization import evaluate_mazes
    from mbn.experiments.trials import route_seconds

    # one time limit for the batch: the longest of the mazes' own (docs/generalization.md)
    seconds = (
        args.seconds if args.seconds is not None else max(route_seconds(m, spec) for m in mazes)
    )
    check_trial_length(loaded, seconds, str(args.controller), limit_name="--seconds")
    key = jax.random.fold_in(jax.random.key(args.seed), NOISE_STREAM) if noise.enabled else None
    result = {"split": split, **evaluate_mazes(mazes, spec, loaded, seconds=seconds, key=key)}
    rows, pooled, at_95 = result["mazes"], result["pooled"], result["mazes_at_95"]
    if noise.enabled:
        result["noise"] = noise.as_dict()
    if args.json:
        print(json_text(result))
        return 0
    what = loaded.kind + (f", program {loaded.program}" if loaded.program else "")
    print(
        f"{args.controller} ({what}) on {split} ({len(mazes)} mazes): behavior "
        f"{args.behavior}"
        + (f" (initial {spec.initial})" if args.behavior == "tiles" else "")
        + f", start marks x {args.repeats}, {args.junctions} junctions, {seconds:g} s"
        + ("" if args.seconds is not None else " (the longest maze's)")
        + (f", noise {_noise_text(noise)}" if noise.enabled else "")
    )
    width = max(len(r["maze"]) for r in rows)
    for r in rows:
        print(
            f"  {r['maze']:<{width}}  {r['successes']:>3}/{r['trials']:<3} "
            f"{r['success_rate']:6.1%}"
            + (f"  {r['timed_out']} timed out" if r["timed_out"] else "")
        )
    print(
        f"  pooled: {pooled['successes']}/{pooled['trials']} successes "
        f"({pooled['success_rate']:.1%}), {pooled['timed_out']} timed out; "
        f"{at_95}/{len(rows)} mazes at >= 95 %"
    )
    return 0
