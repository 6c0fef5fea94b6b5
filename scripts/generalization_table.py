"""The per-seed table of the generalization protocol's targets, from two sweeps of the same seeds:
one of ``mbn reproduce`` (RF, LF, the interpreter with each program, the two-behaviour MBN) and
one of ``mbn run new-behaviours`` (straight-right and straight-left by programs alone through the
fixed full interpreter, the three-behaviour MBN), both with the ``generalization`` stage
(``docs/generalization.md``, "Results over seeds").

Every figure comes from the seeds' own ``results.json`` and the sweeps' ``sweep.json``:

- per controller, on its family's **test split**: pooled success (target >= 95 %) and the mazes
  each at >= 95 % (target >= 90 % of them); on the **zero-shot suite**: pooled (>= 90 %);
- the paper's protocol (10 start marks in ``fig4``) for ``rf``, ``lf``, ``im_rf``, ``im_lf``,
  ``mbn``: every trial;
- the full interpreter's sha256 unchanged in every file the new-behaviours run wrote, and
  checked by its programs and its program module;
- forgetting: the two-behaviour MBN's pooled success on the ``tiles2`` test split (the
  reproduction) minus the three-behaviour MBN's there (new-behaviours), at most 2 points;
- the new-behaviours experiment's other per-run targets (its sweep's "meets every target").

Seeds missing from either sweep, or not finished, are listed as such (never dropped).

    python scripts/generalization_table.py --reproduce runs/gen-reproduce \\
        --new-behaviours runs/gen-nb [--zero-shot] [--json table.json]

A sweep made in installments (a few seeds at a time, each with its own ``--json``) is one table
again with ``--combine``: the installments' seeds side by side, in the order given (a seed in two
installments is refused):

    python scripts/generalization_table.py --combine seeds-0/table.json seeds-1/table.json ...
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from mbn.experiments.sweep.targets import TARGETS, generalization_targets, measure, meets

REPRODUCE = ("rf", "lf", "im_rf", "im_lf", "mbn")
NEW_BEHAVIOURS = ("straight_right", "straight_left", "mbn3")
#: The paper's protocol (every start mark in fig4) of the reproduction's controllers.
PAPER = tuple(t for t in TARGETS if t.name in REPRODUCE)
#: Forgetting: the most the two-behaviour tests may lose when the third behaviour is added.
FORGETTING = 0.02


def _load(path: Path) -> Any:
    return json.loads(path.read_text()) if path.exists() else None


def _seeds(sweep: Path) -> dict[int, dict[str, Any]]:
    data = _load(sweep / "sweep.json")
    if data is None:
        raise SystemExit(f"{sweep}: no sweep.json (not a sweep folder)")
    per_seed = (data.get("summary") or {}).get("per_seed", {})
    return {
        int(k): {**per_seed.get(k, {}), "state": v.get("state")} for k, v in data["runs"].items()
    }


def _split(results: dict[str, Any], name: str, split: str) -> dict[str, Any] | None:
    gen = results.get("stages", {}).get("generalization") or {}
    return ((gen.get("controllers") or {}).get(name) or {}).get("splits", {}).get(split)


def _controller_row(results: dict[str, Any] | None, name: str) -> dict[str, Any]:
    """``[hits, trials]`` and whether each generalization target is met (the sweep's own
    :func:`~mbn.experiments.sweep.targets.meets`), and each zero-shot maze's row."""
    if results is None:
        return {"state": "missing"}
    row: dict[str, Any] = {}
    keys = ("test", "test_mazes", "zero_shot")
    for key, target in zip(keys, generalization_targets(((name, name),)), strict=True):
        hits, trials = measure(target, results)
        if trials:
            row[key] = [hits, trials]
            row[f"{key}_pass"] = meets(target, hits, trials)
    zero = _split(results, name, "zero-shot")
    if zero is not None:
        row["zero_shot_mazes"] = {m["maze"]: [m["successes"], m["trials"]] for m in zero["mazes"]}
    return row


def table(reproduce: Path, new_behaviours: Path) -> dict[str, Any]:
    rep_seeds, nb_seeds = _seeds(reproduce), _seeds(new_behaviours)
    out: dict[str, Any] = {"seeds": {}}
    for seed in sorted(set(rep_seeds) | set(nb_seeds)):
        rep = _load(reproduce / f"seed-{seed}" / "results.json") if seed in rep_seeds else None
        nb = _load(new_behaviours / f"seed-{seed}" / "results.json") if seed in nb_seeds else None
        row: dict[str, Any] = {
            "state": {
                "reproduce": rep_seeds.get(seed, {}).get("state", "missing"),
                "new-behaviours": nb_seeds.get(seed, {}).get("state", "missing"),
            },
            "controllers": {n: _controller_row(rep, n) for n in REPRODUCE}
            | {n: _controller_row(nb, n) for n in NEW_BEHAVIOURS},
        }
        if rep is not None:
            row["paper"] = {t.name: list(measure(t, rep)) for t in PAPER}
            row["paper_pass"] = all(meets(t, *measure(t, rep)) for t in PAPER)
        if nb is not None:
            stages = nb.get("stages", {})
            row["sha256_pass"] = bool(
                stages.get("tests3", {}).get("sha256_unchanged_in")
                and stages.get("programs", {}).get("sha256_checked")
                and stages.get("mbn3", {}).get("sha256_checked")
            )
            row["new_behaviours_targets"] = {
                "meets_all": nb_seeds[seed].get("meets_all"),
                "missed": nb_seeds[seed].get("missed", []),
            }
        two = _split(rep, "mbn", "test") if rep is not None else None
        three = _split(nb, "mbn3_tiles2", "test") if nb is not None else None
        if two is not None and three is not None:
            drop = two["pooled"]["success_rate"] - three["pooled"]["success_rate"]
            row["forgetting"] = drop
            row["forgetting_pass"] = drop <= FORGETTING
        out["seeds"][str(seed)] = row
    return out


def combine(paths: list[Path]) -> dict[str, Any]:
    """The tables of several installments (each written by ``--json``) as one."""
    out: dict[str, Any] = {"seeds": {}}
    for path in paths:
        data = _load(path)
        if not isinstance(data, dict) or not isinstance(data.get("seeds"), dict):
            raise SystemExit(f"{path}: not a table written by --json")
        for seed, row in data["seeds"].items():
            if seed in out["seeds"]:
                raise SystemExit(f"{path}: seed {seed} is in an earlier installment too")
            out["seeds"][seed] = row
    return out


def _pct(hits: int, trials: int) -> str:
    return f"{100 * hits / trials:.1f}"


def _mark(ok: bool | None) -> str:
    return "" if ok else " ✗"


def markdown(data: dict[str, Any], zero_shot: bool) -> str:
    seeds = data["seeds"]
    lines = [
        "Per controller: test pooled % / test mazes at >= 95 % / zero-shot pooled % "
        "(✗: below its target: 95 %, 90 % of the mazes, 90 %).",
        "",
        "| seed | " + " | ".join(REPRODUCE + NEW_BEHAVIOURS) + " | paper 10/10 | sha256 "
        "| forgetting (points) | new-behaviours targets |",
        "|---|" + "---|" * (len(REPRODUCE + NEW_BEHAVIOURS) + 4),
    ]
    counts: dict[str, list[int]] = {}

    def count(key: str, ok: bool | None) -> None:
        if ok is not None:
            c = counts.setdefault(key, [0, 0])
            c[0] += int(bool(ok))
            c[1] += 1

    for seed, row in seeds.items():
        cells = []
        for name in REPRODUCE + NEW_BEHAVIOURS:
            c = row["controllers"][name]
            if "test" not in c:
                cells.append("–")
                continue
            at, n = c["test_mazes"]
            cells.append(
                f"{_pct(*c['test'])}{_mark(c['test_pass'])} / {at}/{n}"
                f"{_mark(c['test_mazes_pass'])} / "
                + (
                    f"{_pct(*c['zero_shot'])}{_mark(c['zero_shot_pass'])}"
                    if "zero_shot" in c
                    else "–"
                )
            )
            ok = c["test_pass"] and c["test_mazes_pass"] and c.get("zero_shot_pass", False)
            count(name, ok)
        paper = "–"
        if "paper" in row:
            paper = ("yes" if row["paper_pass"] else "no: ") + ", ".join(
                f"{n} {s}/{t}" for n, (s, t) in row["paper"].items() if s != t
            )
            count("paper", row["paper_pass"])
        sha = "–" if "sha256_pass" not in row else ("yes" if row["sha256_pass"] else "no")
        count("sha256", row.get("sha256_pass"))
        forget = "–"
        if "forgetting" in row:
            forget = f"{100 * row['forgetting']:+.1f}{_mark(row['forgetting_pass'])}"
            count("forgetting", row["forgetting_pass"])
        nbt = "–"
        if "new_behaviours_targets" in row and row["new_behaviours_targets"]["meets_all"]:
            nbt = "all"
        elif "new_behaviours_targets" in row:
            nbt = "missed " + ", ".join(row["new_behaviours_targets"]["missed"])
        if "new_behaviours_targets" in row:
            count("new-behaviours", bool(row["new_behaviours_targets"]["meets_all"]))
        state = row["state"]
        note = "" if set(state.values()) == {"done"} else f" ({state})"
        lines.append(f"| {seed}{note} | " + " | ".join([*cells, paper, sha, forget, nbt]) + " |")
    lines += ["", "| target | seeds meeting it |", "|---|---|"]
    for key, (hit, total) in counts.items():
        lines.append(f"| {key} | {hit} of {total} |")
    if zero_shot:
        for name in REPRODUCE + NEW_BEHAVIOURS:
            mazes: dict[str, dict[str, str]] = {}
            for seed, row in seeds.items():
                for maze, (s, t) in row["controllers"][name].get("zero_shot_mazes", {}).items():
                    mazes.setdefault(maze, {})[seed] = f"{s}/{t}"
            if not mazes:
                continue
            lines += ["", f"Zero-shot suite, {name}:", ""]
            lines.append("| maze | " + " | ".join(f"seed {s}" for s in seeds) + " |")
            lines.append("|---|" + "---|" * len(seeds))
            for maze, by_seed in mazes.items():
                lines.append(f"| {maze} | " + " | ".join(by_seed.get(s, "–") for s in seeds) + " |")
    return "\n".join(lines)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--reproduce", type=Path, help="a sweep of mbn reproduce")
    p.add_argument("--new-behaviours", type=Path, help="a sweep of mbn run new-behaviours")
    p.add_argument(
        "--combine", type=Path, nargs="+", help="tables of installments (--json) as one table"
    )
    p.add_argument("--zero-shot", action="store_true", help="each zero-shot maze, per seed")
    p.add_argument("--json", type=Path, help="also write the table's figures here")
    args = p.parse_args()
    if args.combine:
        if args.reproduce or args.new_behaviours:
            p.error("--combine takes tables, not sweeps")
        data = combine(args.combine)
    elif args.reproduce and args.new_behaviours:
        data = table(args.reproduce, args.new_behaviours)
    else:
        p.error("give --reproduce and --new-behaviours, or --combine")
    print(markdown(data, args.zero_shot))
    if args.json:
        tmp = args.json.with_suffix(".tmp")
        tmp.write_text(json.dumps(data, indent=1) + "\n")
        tmp.replace(args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
