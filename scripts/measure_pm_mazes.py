"""Measure the program module's last generations driving the robot (``maze_generations``).

``--mbn pm`` (the two-behaviour MBN): for each seed, ``mbn reproduce``'s stages up to ``pm``
run with the defaults (the arm ``reward``: the PM evolved on its program reward alone,
``maze_generations`` 0) into ``OUT/reward/seed-S``. ``--mbn mbn3`` (the three-behaviour MBN):
``mbn run new-behaviours``' stages up to ``mbn3``. Each other arm copies that folder and runs
the PM's stage again with its setting: its reward's DE and attempts resume from the copied
checkpoints (the same keys), and the generations driving the robot in mazes of the tile
family's train split follow. Every arm's MBN is then judged on mazes no stage chooses on: by
default 100 mazes of the tile family's train split far beyond any run's pool
(``tiles2/train:900000-900099``, ``tiles3/...``; how many of them lay in the run's pool is
recorded), every start mark once, as the test split is judged. One JSON line per arm and seed
is appended to ``OUT/measure.jsonl`` (the judged figures, the validation the stage chose on, the
stage's seconds); done pairs are skipped, so the script resumes.

The test split is never touched: this chooses a setting (``docs/generalization.md``, "The
program module driving the robot").

    python scripts/measure_pm_mazes.py --mbn mbn3 --out runs/pm3-measure --seeds 30-34
    python scripts/measure_pm_mazes.py --out runs/pm3-measure --summary
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path
from typing import Any

# the seed list and the resumption of measure_episodes.py, beside this script
from measure_episodes import _done, _seeds

#: The arms: name -> ``maze_generations`` (the generations run where the reward's MBN misses its
#: validation target, the better MBN by validation kept). The first measurement's arm
#: ``mazes-50`` ran them after every reward and kept their MBN (``docs/generalization.md``): its
#: rows stay in ``measure.jsonl`` and the summary leaves them out.
ARMS: dict[str, int] = {"reward": 0, "mend-50": 50, "mend-150": 150}
#: Per MBN: the experiment's name, its stages up to the PM's (the base run), the PM's stage,
#: its controller file and its tile family.
MBNS: dict[str, tuple[str, list[str], str, str, str]] = {
    "pm": ("reproduce", ["multiplier", "rf", "lf_search", "lf", "im", "pm"], "pm", "mbn", "tiles2"),
    "mbn3": (
        "new-behaviours",
        ["multiplier", "rf", "lf_search", "lf", "im_full", "programs", "mbn3"],
        "mbn3",
        "mbn3",
        "tiles3",
    ),
}


def _experiment(mbn: str) -> Any:
    from mbn.experiments.behaviours import NEW_BEHAVIOURS
    from mbn.experiments.reproduce import REPRODUCE

    return {"reproduce": REPRODUCE, "new-behaviours": NEW_BEHAVIOURS}[MBNS[mbn][0]]


def _base(out: Path, mbn: str, seed: int) -> Path:
    from mbn.experiments.pipeline.runner import run_experiment

    exp = _experiment(mbn)
    folder = out / "reward" / f"seed-{seed}"
    folder.parent.mkdir(parents=True, exist_ok=True)
    run_experiment(
        exp,
        folder,
        seed=seed,
        config=exp.config(quick=False),
        resume=(folder / "run.json").exists(),
        log=lambda _m: None,
        stages=MBNS[mbn][1],
        workers=2,
        # a base made before a change that leaves maze_generations 0 as it was (recorded)
        allow_other_code=True,
    )
    return folder


def _arm_folder(out: Path, mbn: str, arm: str, seed: int, base: Path) -> Path:
    """The arm's copy of the base run, the PM's stage run again with the arm's setting."""
    from mbn.experiments.pipeline import RunDir
    from mbn.experiments.pipeline.runner import replace_section, run_stage

    exp = _experiment(mbn)
    _, _, stage, controller, _ = MBNS[mbn]
    folder = out / arm / f"seed-{seed}"
    if not (folder / "run.json").exists():
        if folder.exists():
            shutil.rmtree(folder)
        shutil.copytree(base, folder)
        for path in (
            folder / "stages" / f"{stage}.json",
            folder / "controllers" / f"{controller}.json",
        ):
            path.unlink(missing_ok=True)
    rundir = RunDir(folder)
    config = exp.config(quick=False)
    config = replace_section(config, config[stage].replace(maze_generations=ARMS[arm]))
    if not rundir.stage_file(stage).exists():
        run_stage(exp, rundir, stage, seed=seed, config=config)
    return folder


def measure(out: Path, mbn: str, arm: str, seed: int, judge_on: str) -> dict[str, Any]:
    from mbn.controllers import make_controller, read_controller_spec
    from mbn.experiments.generalization import evaluate_mazes
    from mbn.experiments.maze_task import MazeTask
    from mbn.experiments.stages.settings import EpisodeSettings
    from mbn.experiments.trials import TrialSpec
    from mbn.precision import ROBOT, scope
    from mbn.world.mazes.load import load_mazes

    exp = _experiment(mbn)
    _, _, stage, controller, family = MBNS[mbn]
    base = _base(out, mbn, seed)
    t0 = time.perf_counter()
    folder = base if ARMS[arm] == 0 else _arm_folder(out, mbn, arm, seed, base)
    wall = time.perf_counter() - t0  # the arm's PM stage again (0 for the base's own)
    pm = json.loads((folder / "stages" / f"{stage}.json").read_text())
    mazes, split = load_mazes(judge_on or f"{family}/train:900000-900099")
    episodes = exp.config(quick=False).get(EpisodeSettings)
    pool = set(
        MazeTask(
            rule="tiles",
            family=family,
            pool=episodes.pool,
            seed=exp.seeds(seed)["crossroad_jitter"],
        ).pool_seeds()
    )
    in_pool = sum(int(m.name.split(":")[1]) in pool for m in mazes if ":" in m.name)
    with scope(ROBOT):  # as `mbn evaluate` and the runs judge
        spec = read_controller_spec(folder / "controllers" / f"{controller}.json")
        loaded = make_controller(spec, None, check_stability=False)
        trial = TrialSpec(
            behavior="tiles",
            initial=loaded.initial_rule or "right",
            tile_rules=tuple(loaded.tile_rules or ("right", "left")),
        )
        judged = evaluate_mazes(mazes, trial, loaded)
    return {
        "mbn": mbn,
        "arm": arm,
        "seed": seed,
        "maze_generations": ARMS[arm],
        "split": split,
        "judged_mazes_in_training_pool": in_pool,
        "pooled": judged["pooled"],
        "mazes_at_95": judged["mazes_at_95"],
        "validation": pm.get("validation"),
        "attempts": len(pm.get("attempts") or [None]),
        "chosen_attempt": pm.get("chosen_attempt"),
        "maze_fitness": (pm.get("maze") or {}).get("best_fitness"),
        "base_pm_seconds": json.loads((base / "timings.json").read_text())["stages"][stage],
        "arm_pm_seconds_this_call": round(wall, 1),
    }


def summary(out: Path) -> None:
    rows = [json.loads(x) for x in (out / "measure.jsonl").read_text().splitlines()]
    arms = [a for a in ARMS if any(r["arm"] == a for r in rows)]
    print(
        "| arm | seeds | judged pooled (each seed) | judged mazes at >= 95 % (each seed) "
        "| validation mazes at target (each seed) | attempts (each seed) |"
    )
    print("|---|---|---|---|---|---|")
    for arm in arms:
        rs = sorted((r for r in rows if r["arm"] == arm), key=lambda r: r["seed"])
        pooled = ", ".join(f"{r['pooled']['success_rate']:.1%}" for r in rs)
        print(
            f"| {arm} | {','.join(str(r['seed']) for r in rs)} "
            f"| {pooled} "
            f"| {', '.join(str(r['mazes_at_95']) for r in rs)} "
            f"| {', '.join(str(r['validation'].get('mazes_at_target')) for r in rs)} "
            f"| {', '.join(str(r['attempts']) for r in rs)} |"
        )


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--mbn", choices=sorted(MBNS), default="pm", help="which MBN's PM (default pm)")
    p.add_argument("--seeds", default="30-34")
    p.add_argument("--arms", default=",".join(ARMS), help="comma-separated arms (default all)")
    p.add_argument("--summary", action="store_true", help="print the table of what is measured")
    p.add_argument(
        "--judge",
        default="",
        help="the mazes the MBNs are judged in (default: 100 train mazes of the MBN's tile "
        "family no run draws, FAMILY/train:900000-900099; never the validation split the stage "
        "chose on, never a test split)",
    )
    args = p.parse_args()
    family_split = args.judge.split(":")[0]
    if family_split.endswith("/test") or family_split.endswith("/validation"):
        print(
            "--judge: the test split is only ever a test, and the stage chooses on the "
            "validation split: judge on train mazes outside the pool",
            file=sys.stderr,
        )
        return 2
    if args.summary:
        summary(args.out)
        return 0
    arms = args.arms.split(",")
    for arm in arms:
        if arm not in ARMS:
            print(f"no arm {arm!r} (the arms: {', '.join(ARMS)})", file=sys.stderr)
            return 2
    args.out.mkdir(parents=True, exist_ok=True)
    for seed in _seeds(args.seeds):
        for arm in arms:
            if (arm, seed) in _done(args.out):
                continue
            row = measure(args.out, args.mbn, arm, seed, args.judge)
            with open(args.out / "measure.jsonl", "a") as f:
                f.write(json.dumps(row) + "\n")
            print(
                f"{arm} seed {seed}: {row['pooled']['success_rate']:.1%} pooled, "
                f"{row['mazes_at_95']} mazes at >= 95 %; validation "
                f"{row['validation'].get('mazes_at_target')} mazes at target; "
                f"{row['attempts']} attempt(s)",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
