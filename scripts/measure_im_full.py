"""Measure the fully programmable interpreter's faithfulness against its multipliers' time
constant: for each run folder given (one holding ``controllers/multiplier.json``, ``rf.json`` and
``lf.json``, such as a ``new-behaviours`` or ``reproduce`` run) and each arm (``[im_full]
tau_ratio`` and ``substeps``, keeping the multiplier's training step h / tau_m = 0.1), build the
``im_full`` stage's interpreter of the run's RF and run RF's and LF's programs through it on the
stage's own tests (the paper's protocol, the jittered ``fig4`` and the held-out maze, with the
run's own test seeds), beside RF and LF themselves. One JSON line per run and arm is appended to
``OUT``: each test's successes, the agreement with the plain network, and the seconds the
emulated trials took. Done pairs are skipped, so the script resumes where it stopped.

With ``--grid MAZES`` (a split or range as ``mbn evaluate --maze`` takes it, such as
``grid/train:900000-900099``: mazes no run chooses on), RF's and LF's programs through the
interpreter and RF and LF themselves are judged there as well, each start mark once. With
``--mbn3 MAZES`` (``tiles3/train:900000-900099``), the run's three-behaviour MBN
(``controllers/mbn3.json``) is judged there, its interpreter rebuilt at each arm's time
constant (the program module as it is: it reads the camera and writes a program, whatever the
interpreter's multipliers), as the ``generalization`` stage judges it. Both refuse a family's
test split: a test is never where a setting is chosen.

The stage's own tests are hand-made test mazes (``fig4`` jittered, the held-out maze): give
the script runs of seeds that no sweep reports, and choose on ``--grid`` and ``--mbn3``
(``docs/behaviours.md``).

    python scripts/measure_im_full.py --out runs/im-full-measure.jsonl \
        runs/select-measure/select-default/seed-2? --arms 0.025:80,0.0125:160
    python scripts/measure_im_full.py --out runs/im-full-measure.jsonl --summary
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any


def _arms(text: str) -> list[tuple[float, int]]:
    arms = []
    for part in text.split(","):
        ratio, _, steps = part.partition(":")
        try:
            arms.append((float(ratio), int(steps)))
        except ValueError:
            raise SystemExit(f"--arms: {part!r} is not TAU_RATIO:SUBSTEPS") from None
    return arms


def _done(out: Path) -> set[tuple[str, float, int]]:
    if not out.exists():
        return set()
    rows = map(json.loads, out.read_text().splitlines())
    return {(r["run"], r["tau_ratio"], r["substeps"]) for r in rows}


def measure(
    run: Path,
    tau_ratio: float,
    substeps: int,
    mbn3: str | None = None,
    grid: str | None = None,
) -> dict[str, Any]:
    import numpy as np

    from mbn.controllers import CTRNNControllerSpec, make_controller, read_controller_spec
    from mbn.experiments.behaviours import NEW_BEHAVIOURS
    from mbn.experiments.stages.im_full import (
        IMFullSettings,
        full_interpreter,
        full_interpreter_spec,
        reference_controller,
    )
    from mbn.experiments.stages.protocol import SUFFIXES, test_specs
    from mbn.experiments.stages.tests import TestsSettings
    from mbn.experiments.trials import agreement, run_loaded_trials, summary
    from mbn.networks.multiplier import load_multiplier
    from mbn.networks.programmable import Connection
    from mbn.world.mazes.load import load_maze

    manifest = json.loads((run / "run.json").read_text())
    seed = int(manifest["seed"])
    seeds = NEW_BEHAVIOURS.seeds(seed)
    nets = {}
    for name in ("rf", "lf"):
        spec = read_controller_spec(run / "controllers" / f"{name}.json")
        if not isinstance(spec, CTRNNControllerSpec):
            raise SystemExit(f"{run}/controllers/{name}.json: not a CTRNN controller")
        nets[name] = spec.net
    mul = load_multiplier(run / "controllers" / "multiplier.json")
    s = IMFullSettings(tau_ratio=tau_ratio, substeps=substeps)
    t = TestsSettings()
    interp = full_interpreter(nets["rf"], [Connection.parse(c) for c in s.connections], mul, s)
    emulated_spec = full_interpreter_spec(interp, nets["rf"], nets["lf"], s, {})
    mazes = {
        "": load_maze(t.maze),
        "_jitter": load_maze(t.maze),
        "_heldout": load_maze(t.heldout_maze),
    }
    row: dict[str, Any] = {
        "run": str(run),
        "seed": seed,
        "tau_ratio": tau_ratio,
        "substeps": substeps,
        "tests": {},
        "agreement": {},
        "emulated_seconds": 0.0,
    }
    for rule, short in (("right", "rf"), ("left", "lf")):
        specs = test_specs(
            rule,
            seconds=t.seconds,
            jitter_per_mark=t.jitter_per_mark,
            heldout_repeats=t.heldout_repeats,
            test_seed=seeds["test_jitter"],
            heldout_seed=seeds["heldout_jitter"],
        )
        plain = reference_controller(nets[short], rule)
        emulated = make_controller(emulated_spec, rule, where="im_full", check_stability=False)
        for suffix in SUFFIXES:
            ref, _, _ = run_loaded_trials(mazes[suffix], specs[suffix], plain)
            t0 = time.perf_counter()
            got, _, _ = run_loaded_trials(mazes[suffix], specs[suffix], emulated)
            row["emulated_seconds"] += time.perf_counter() - t0
            key = f"im_full_{short}{suffix}"
            row["tests"][key] = summary(got)
            row["tests"][f"{short}{suffix}"] = summary(ref)
            row["agreement"][key] = agreement(got, ref)
    row["emulated_seconds"] = round(row["emulated_seconds"], 1)
    if grid is not None:
        row["grid"] = _followers(nets, emulated_spec, grid, seeds["test_jitter"])
    if mbn3 is not None:
        row["mbn3"] = _mbn3(run, nets["rf"], mul, tau_ratio, substeps, mbn3, seeds["test_jitter"])

    def plain(o: Any) -> Any:
        return o.to_json() if hasattr(o, "to_json") else float(np.asarray(o))

    return dict(json.loads(json.dumps(row, default=plain)))


def _refuse_test(where: str, split: str | None) -> None:
    if split and split.partition("/")[2].partition(":")[0] == "test":
        raise SystemExit(f"{where}: a test split; judge on train or validation mazes")


def _followers(nets: dict[str, Any], emulated_spec: Any, where: str, seed: int) -> dict[str, Any]:
    """RF's and LF's programs through the interpreter, and RF and LF themselves, in the mazes
    ``where`` names, each start mark once (pooled and mazes at 95 % for each)."""
    from mbn.controllers import make_controller
    from mbn.experiments.generalization import evaluate_mazes
    from mbn.experiments.stages.im_full import reference_controller
    from mbn.experiments.trials import TrialSpec
    from mbn.world.mazes.load import load_mazes

    mazes, split = load_mazes(where)
    _refuse_test(where, split)
    out: dict[str, Any] = {"mazes": where}
    for rule, short in (("right", "rf"), ("left", "lf")):
        trial = TrialSpec(behavior=rule, seed=seed)
        for name, loaded in (
            (short, reference_controller(nets[short], rule)),
            (f"im_full_{short}", make_controller(emulated_spec, rule, check_stability=False)),
        ):
            judged = evaluate_mazes(mazes, trial, loaded)
            out[name] = {"pooled": judged["pooled"], "mazes_at_95": judged["mazes_at_95"]}
    return out


def _mbn3(
    run: Path, rf: Any, mul: Any, tau_ratio: float, substeps: int, where: str, seed: int
) -> dict[str, Any]:
    """The run's three-behaviour MBN, its interpreter rebuilt at ``tau_ratio`` and
    ``substeps``, judged in the mazes ``where`` names (pooled, mazes at 95 %, seconds)."""
    import dataclasses

    from mbn.controllers import make_controller, read_controller_spec
    from mbn.experiments.generalization import evaluate_mazes
    from mbn.experiments.trials import TrialSpec
    from mbn.networks.programmable import Programmable, build_interpreter
    from mbn.world.mazes.load import load_mazes

    spec = read_controller_spec(run / "controllers" / "mbn3.json")
    im = spec.interpreter_spec
    old = im.interpreter
    new = build_interpreter(
        rf,
        [
            Programmable(c, float(lo), float(hi))
            for c, lo, hi in zip(old.connections, old.lower, old.upper, strict=True)
        ],
        mul,
        tau_ratio=tau_ratio,
    )
    spec = dataclasses.replace(
        spec, interpreter_spec=dataclasses.replace(im, interpreter=new, substeps=substeps)
    )
    loaded = make_controller(spec, None, check_stability=False)
    tile_rules = tuple(loaded.tile_rules or ("right", "left"))
    trial = TrialSpec(
        behavior="tiles",
        initial=loaded.initial_rule or "right",
        seed=seed,
        tile_rules=tile_rules,
    )
    mazes, split = load_mazes(where)
    _refuse_test(where, split)
    t0 = time.perf_counter()
    judged = evaluate_mazes(mazes, trial, loaded)
    return {
        "mazes": where,
        "split": split,
        "same_interpreter_as_the_file": new.digest() == old.digest(),
        "pooled": judged["pooled"],
        "mazes_at_95": judged["mazes_at_95"],
        "seconds": round(time.perf_counter() - t0, 1),
    }


def summarize(out: Path) -> None:
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    print(
        "| seed | tau_ratio | sub-steps | LF's program: 10 / 200 jittered / 204 held out | "
        "agreement with LF (jittered) | RF's program: 200 jittered | LF itself: 200 jittered | "
        "seconds |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for r in sorted(rows, key=lambda r: (r["seed"], -r["tau_ratio"])):
        t, a = r["tests"], r["agreement"]
        print(
            f"| {r['seed']} | {r['tau_ratio']:g} | {r['substeps']} | "
            f"{t['im_full_lf']['successes']} / {t['im_full_lf_jitter']['successes']} / "
            f"{t['im_full_lf_heldout']['successes']} | {a['im_full_lf_jitter']['rate']:.1%} | "
            f"{t['im_full_rf_jitter']['successes']} | {t['lf_jitter']['successes']} | "
            f"{r['emulated_seconds']:.0f} |"
        )
    with_grid = [r for r in rows if "grid" in r]
    if with_grid:
        print()
        print("| seed | tau_ratio | sub-steps | mazes | RF | RF's program | LF | LF's program |")
        print("|---|---|---|---|---|---|---|---|")
        for r in sorted(with_grid, key=lambda r: (r["seed"], -r["tau_ratio"])):
            g = r["grid"]
            cells = [
                f"{g[k]['pooled']['successes']}/{g[k]['pooled']['trials']}, {g[k]['mazes_at_95']}"
                for k in ("rf", "im_full_rf", "lf", "im_full_lf")
            ]
            print(
                f"| {r['seed']} | {r['tau_ratio']:g} | {r['substeps']} | {g['mazes']} | "
                + " | ".join(cells)
                + " |"
            )
    with_mbn3 = [r for r in rows if "mbn3" in r]
    if with_mbn3:
        print()
        print(
            "| seed | tau_ratio | sub-steps | mazes | three-behaviour MBN: pooled | mazes at 95 % |"
        )
        print("|---|---|---|---|---|---|")
        for r in sorted(with_mbn3, key=lambda r: (r["seed"], -r["tau_ratio"])):
            m = r["mbn3"]
            pooled = m["pooled"]
            print(
                f"| {r['seed']} | {r['tau_ratio']:g} | {r['substeps']} | {m['mazes']} | "
                f"{pooled['successes']}/{pooled['trials']} | {m['mazes_at_95']} |"
            )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="*", type=Path, help="run folders (their seeds' runs)")
    parser.add_argument("--out", type=Path, required=True, help="JSON lines file, appended to")
    parser.add_argument("--arms", default="0.025:80,0.0125:160", help="TAU_RATIO:SUBSTEPS,...")
    parser.add_argument("--mbn3", default=None, metavar="MAZES", help="judge mbn3.json there too")
    parser.add_argument(
        "--grid", default=None, metavar="MAZES", help="judge RF's and LF's programs there too"
    )
    parser.add_argument("--summary", action="store_true", help="print the table of OUT")
    args = parser.parse_args()
    if args.summary:
        summarize(args.out)
        return 0
    done = _done(args.out)
    for run in args.runs:
        for ratio, steps in _arms(args.arms):
            if (str(run), ratio, steps) in done:
                continue
            row = measure(run, ratio, steps, args.mbn3, args.grid)
            with args.out.open("a") as f:
                f.write(json.dumps(row) + "\n")
            lf = row["tests"]["im_full_lf_jitter"]
            print(f"{run} tau_ratio {ratio:g} x{steps}: LF's program {lf['successes']}/200")
    return 0


if __name__ == "__main__":
    sys.exit(main())
