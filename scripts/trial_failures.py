"""Where a controller's trials fail in a maze family's split: how each failed trial failed (a
wrong exit, stalling in more than 2 % of its steps, time out), the junctions of the wrong exits
(free neighbours of the cell, the exit taken, the rule's), and the kind of cell each stalled
step lies in (the trials run again with every step recorded). For diagnosis: run it on the
validation split (a test maze looked into becomes a validation maze).

Usage: python scripts/trial_failures.py CONTROLLER.json --behavior right [--maze grid/validation]
    [--record 30]  (docs/generalization.md, "Before")
"""

from __future__ import annotations

import argparse
import collections
import dataclasses

import jax
import numpy as np

from mbn.controllers import make_controller, read_controller_spec
from mbn.experiments.trials import TrialGroup, TrialSpec, route_seconds, run_trial_groups
from mbn.world.junctions import cell_of, decision_cells, free_neighbours
from mbn.world.mazes.load import load_mazes
from mbn.world.rules import rule_exit_codes


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("controller")
    parser.add_argument("--behavior", required=True, help="the rule judged (and program)")
    parser.add_argument("--maze", default="grid/validation")
    parser.add_argument("--record", type=int, default=30, help="mazes whose steps are recorded")
    args = parser.parse_args()
    mazes, _ = load_mazes(args.maze)
    spec_file = read_controller_spec(args.controller)
    program = args.behavior if spec_file.kind == "mbn.controller.interpreter" else None
    loaded = make_controller(spec_file, program)
    spec = TrialSpec(behavior=args.behavior, junctions=3)
    spec = dataclasses.replace(spec, seconds=max(route_seconds(m, spec) for m in mazes))

    def run(ms: list, record: int):
        groups = [TrialGroup(m.name, i, spec, loaded.initial_state) for i, m in enumerate(ms)]
        return run_trial_groups(
            ms,
            groups,
            loaded.controller,
            seconds=spec.seconds,
            dt=loaded.dt,
            sensors=loaded.sensors,
            record_every=record,
        )

    verdicts, result, slices, _ = run(mazes, 0)
    stats = jax.tree.map(np.asarray, result.stats)
    how: collections.Counter = collections.Counter()
    wrong_at: collections.Counter = collections.Counter()
    for m in mazes:
        v, sl = verdicts[m.name], slices[m.name]
        count = free_neighbours(m).sum(-1)
        for t in np.nonzero(~v["success"])[0]:
            b = sl.start + t
            want = rule_exit_codes(args.behavior, stats.junction_open[b, :3])
            exits = v["exits"][t]
            wrong = [k for k in range(3) if exits[k] >= 0 and exits[k] != want[k]]
            if wrong:
                r, c = stats.junction_cell[b, wrong[0]]
                wrong_at[(int(count[r, c]), int(exits[wrong[0]]), int(want[wrong[0]]))] += 1
                how["wrong exit"] += 1
            elif v["stall"][t] > 0.02:
                how["stall"] += 1
            else:
                how["timed out"] += 1
    print(f"failed trials: {dict(how)} of {sum(len(v['success']) for v in verdicts.values())}")
    print(
        "wrong exits by (free neighbours of the cell, exit taken, rule's exit; 0 back 1 right "
        f"2 straight 3 left): {dict(wrong_at)}"
    )
    recorded = mazes[: args.record]
    _, result, slices, _ = run(recorded, 1)
    stalled, pose = np.asarray(result.trajectory.stalled), np.asarray(result.trajectory.pose)
    where: collections.Counter = collections.Counter()
    for m in recorded:
        count, decision = free_neighbours(m).sum(-1), decision_cells(m)
        for b in range(slices[m.name].start, slices[m.name].stop):
            for s in np.nonzero(stalled[b])[0]:
                r, c = cell_of(m, *pose[b, s, :2])
                k = int(count[r, c])
                where[
                    {1: "dead end", 3: "T", 4: "plus"}.get(
                        k, "corner" if decision[r, c] else "straight"
                    )
                ] += 1
    total = sum(where.values()) or 1
    print(
        f"stalled steps in the first {len(recorded)} mazes by cell kind: "
        + ", ".join(f"{k} {n} ({n / total:.0%})" for k, n in where.most_common())
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
