"""Measure how the followers' maze episodes are drawn: every N generations, and how many.

For each arm (a named ``[episodes]`` / ``[followers]`` override of ``mbn reproduce``'s defaults)
and each seed, run the ``rf`` stage of ``mbn reproduce`` (with the multiplier it needs; with
``--lf`` the LF search and LF as well) into ``OUT/ARM/seed-S``, then judge its right-follower
(and left-follower) on the ``grid`` family's **validation** split
(100 mazes, every start mark once, as ``mbn evaluate --maze grid/validation``), or on the mazes
``--judge`` names (the ``select-*`` arms choose among candidates on the validation split, so
they are judged on train mazes outside every run's pool, ``grid/train:900000-900099``; how many
of the judged mazes were in the run's pool is recorded). One JSON line per
arm and seed is appended to ``OUT/measure.jsonl``: the validation figures, the stage's seconds
and robot-steps. Done pairs are skipped, so the script resumes where it stopped (a stage resumes
from its checkpoints).

Seeds are visited in order and the arms round-robin within a seed, so that a partial
measurement is balanced. The test split is never touched: this chooses settings
(``docs/generalization.md``, "The N measurement").

    python scripts/measure_episodes.py --out runs/n-measure --seeds 0-4
    python scripts/measure_episodes.py --out runs/n-measure --summary
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any


def _arm(
    mazes: int, starts: int, redraw: int, search_starts: int, rf: int = 300, lf: int = 70
) -> dict[str, dict[str, Any]]:
    """The settings of a maze-episode arm: draws of ``mazes`` x ``starts``, drawn again every
    ``redraw`` generations, the LF search on ``search_starts`` starts of each maze, RF evolved
    ``rf`` generations and each LF finalist ``lf`` (pinned: the defaults changed after the
    first arms were run with 300 and 70)."""
    episodes = {"kind": "maze", "mazes": mazes, "starts": starts, "redraw": redraw}
    return {
        "episodes": {**episodes, "search_starts": search_starts},
        "rf": {"generations": rf},
        "lf": {"generations": lf},
    }


#: The arms: name -> settings sections. ``redraw`` 0 draws the episodes once (never again).
ARMS: dict[str, dict[str, dict[str, Any]]] = {
    # draws of 4 mazes x 4 starts; the LF search on every start of a draw (as before
    # ``search_starts`` existed)
    **{f"n{n}": _arm(4, 4, n, 4) for n in (0, 1, 10, 50)},
    "n10-32ep": _arm(8, 4, 10, 4),
    # draws of 3 mazes x 3 starts: 9 episodes of 60 s, a genome's evaluation about as long as
    # the seven crossroads' 28 episodes of 20 s
    **{f"n{n}-9ep": _arm(3, 3, n, 3) for n in (0, 1, 10, 50)},
    # 4 x 4, N = 10, cheaper: the LF search on 2 starts of each maze, RF evolved 150 generations
    # (its training fitness levels off by about generation 40 on maze episodes), each LF
    # finalist 35 (the defaults since)
    "lean": _arm(4, 4, 10, 2, rf=150, lf=35),
    # the same, drawn again every N generations for other N: never, every generation, 50
    **{f"lean-n{n}": _arm(4, 4, n, 2, rf=150, lf=35) for n in (0, 1, 50)},
    # the final choice among candidates (RF restarts, LF finalists) on the test's own criterion:
    # every start mark once in each of the validation split's 100 mazes, a maze passing with
    # every trial, 90 % of them passing (the defaults: 20 mazes, 2 starts a mark); judged on
    # mazes no run chooses on (--judge grid/train:900000-900099), never the validation split it
    # chose on
    "select-default": {},
    "select-val100": {"validation": {"split_mazes": 100, "split_jitter_per_mark": 1}},
    # the paper's protocol (docs/configs/paper.toml)
    "crossroads": {
        "episodes": {"kind": "crossroads"},
        "rf": {"generations": 300},
        "lf": {"generations": 70},
    },
}


def _toml(sections: dict[str, dict[str, Any]]) -> str:
    lines = []
    for name, values in sections.items():
        lines.append(f"[{name}]")
        for k, v in values.items():
            lines.append(f"{k} = {json.dumps(v)}")
    return "\n".join(lines) + "\n"


def _seeds(text: str) -> list[int]:
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(s) for s in text.split(",")]


def _done(out: Path) -> set[tuple[str, int]]:
    path = out / "measure.jsonl"
    if not path.exists():
        return set()
    return {(r["arm"], r["seed"]) for r in map(json.loads, path.read_text().splitlines())}


def measure(
    out: Path, arm: str, seed: int, lf: bool = False, judge_on: str = "grid/validation"
) -> dict[str, Any]:
    from mbn.config import read_toml
    from mbn.controllers import make_controller, read_controller_spec
    from mbn.experiments.generalization import evaluate_mazes
    from mbn.experiments.pipeline.runner import run_experiment
    from mbn.experiments.reproduce import REPRODUCE
    from mbn.experiments.stages.settings import EpisodeSettings
    from mbn.experiments.trials import TrialSpec
    from mbn.precision import ROBOT, scope
    from mbn.world.mazes.load import load_mazes

    folder = out / arm / f"seed-{seed}"
    folder.parent.mkdir(parents=True, exist_ok=True)
    config_file = out / arm / "config.toml"
    config_file.write_text(_toml(ARMS[arm]))
    config = REPRODUCE.config(quick=False, document=read_toml(config_file))
    t0 = time.perf_counter()
    run_experiment(
        REPRODUCE,
        folder,
        seed=seed,
        config=config,
        resume=(folder / "run.json").exists(),
        log=lambda _m: None,
        stages=["rf", "lf_search", "lf"] if lf else ["rf"],
        workers=2,
    )
    wall = time.perf_counter() - t0
    timings = json.loads((folder / "timings.json").read_text())
    rf = json.loads((folder / "stages" / "rf.json").read_text())
    mazes, split = load_mazes(judge_on)
    # mazes of the family's train split that the run's episodes were drawn from (its pool)
    from mbn.experiments.maze_task import MazeTask

    episodes = config.get(EpisodeSettings)
    pool = set(
        MazeTask(
            family=episodes.family,
            pool=episodes.pool,
            seed=REPRODUCE.seeds(seed)["crossroad_jitter"],
        ).pool_seeds()
    )
    in_pool = sum(int(m.name.split(":")[1]) in pool for m in mazes if ":" in m.name)

    def judge(name: str, behavior: str) -> dict[str, Any]:
        with scope(ROBOT):  # as `mbn evaluate` judges
            spec = read_controller_spec(folder / "controllers" / f"{name}.json")
            # as the runs judge them: an evolved network may step beyond its integrator's
            # stability limit and still be what the run kept and tested
            loaded = make_controller(spec, None, check_stability=False)
            return evaluate_mazes(mazes, TrialSpec(behavior=behavior), loaded)

    judged = judge("rf", "right")
    row: dict[str, Any] = {
        "arm": arm,
        "seed": seed,
        "settings": ARMS[arm],
        "split": split,
        "judged_mazes_in_training_pool": in_pool,
        "pooled": judged["pooled"],
        "mazes_at_95": judged["mazes_at_95"],
        "rf_seconds": timings["stages"]["rf"],
        "rf_robot_steps": timings["robot_steps"]["rf"],
        "restarts": len(rf.get("restarts", [])) or 1,
        "best_fitness": rf["best_fitness"],
        "wall_seconds_this_call": round(wall, 1),
    }
    if lf:
        judged_lf = judge("lf", "left")
        row["lf"] = {
            "pooled": judged_lf["pooled"],
            "mazes_at_95": judged_lf["mazes_at_95"],
            "seconds": {k: timings["stages"][k] for k in ("lf_search", "lf")},
            "robot_steps": {k: timings["robot_steps"][k] for k in ("lf_search", "lf")},
        }
    return row


def summary(out: Path) -> None:
    rows = [json.loads(x) for x in (out / "measure.jsonl").read_text().splitlines()]
    arms = sorted({r["arm"] for r in rows}, key=list(ARMS).index)
    print(
        "| arm | seeds | pooled (each seed) | mazes at >= 95 % (each seed) "
        "| RF robot-steps (M, mean) | LF pooled (each seed) | LF mazes at >= 95 % "
        "| LF search + LF robot-steps (M, mean) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for arm in arms:
        rs = sorted((r for r in rows if r["arm"] == arm), key=lambda r: r["seed"])
        pooled = ", ".join(f"{r['pooled']['success_rate']:.1%}" for r in rs)
        at = ", ".join(str(r["mazes_at_95"]) for r in rs)
        steps = sum(r["rf_robot_steps"] for r in rs) / len(rs) / 1e6
        seeds = ",".join(str(r["seed"]) for r in rs)
        lfs = [r["lf"] for r in rs if "lf" in r]
        lf_pooled = ", ".join(f"{x['pooled']['success_rate']:.1%}" for x in lfs) or "-"
        lf_at = ", ".join(str(x["mazes_at_95"]) for x in lfs) or "-"
        lf_steps = (
            f"{sum(sum(x['robot_steps'].values()) for x in lfs) / len(lfs) / 1e6:.0f}"
            if lfs
            else "-"
        )
        print(
            f"| {arm} | {seeds} | {pooled} | {at} | {steps:.0f} | {lf_pooled} | {lf_at} "
            f"| {lf_steps} |"
        )


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--seeds", default="0-4")
    p.add_argument("--arms", default=",".join(ARMS), help="comma-separated arms (default all)")
    p.add_argument("--summary", action="store_true", help="print the table of what is measured")
    p.add_argument(
        "--lf",
        action="store_true",
        help="also run the LF search and LF, and judge LF on the validation split (left)",
    )
    p.add_argument(
        "--judge",
        default="grid/validation",
        help="the mazes the followers are judged in (default the validation split; the "
        "select-* arms choose on it, so judge them elsewhere: grid/train:900000-900099)",
    )
    args = p.parse_args()
    if args.judge.split(":")[0].endswith("/test"):
        print("--judge: the test split is only ever a test", file=sys.stderr)
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
            row = measure(args.out, arm, seed, lf=args.lf, judge_on=args.judge)
            with open(args.out / "measure.jsonl", "a") as f:
                f.write(json.dumps(row) + "\n")
            print(
                f"{arm} seed {seed}: {row['pooled']['success_rate']:.1%} pooled, "
                f"{row['mazes_at_95']} mazes at >= 95 %, {row['rf_robot_steps'] / 1e6:.0f} M "
                f"robot-steps, {row['rf_seconds']:.0f} s"
                + (
                    f"; LF {row['lf']['pooled']['success_rate']:.1%} pooled, "
                    f"{row['lf']['mazes_at_95']} mazes at >= 95 %"
                    if "lf" in row
                    else ""
                ),
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
