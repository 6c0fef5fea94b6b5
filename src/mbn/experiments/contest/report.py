"""The claims and the report of ``mbn run programs-vs-dynamics`` (one seed's run; the
statistics over runs are the sweep's, :mod:`mbn.experiments.contest.over_runs`)."""

from __future__ import annotations

from typing import Any

from mbn.experiments.contest.over_runs import CLAIM_2016, CRITERION, checks_text
from mbn.experiments.pipeline import RunDir
from mbn.experiments.pipeline.document import Section, claims_section, write_document
from mbn.experiments.pipeline.results import RunResults
from mbn.experiments.stages.contest import ContestResult, ContestRun, ContestStage
from mbn.experiments.stages.contest3 import TASK, Contest3Result, Contest3Stage
from mbn.experiments.stages.records import Tally
from mbn.io import read_json

__all__ = ["TITLE", "claims", "write_report"]

TITLE = "mbn: learning programs against learning dynamics"


def _records(stages: dict[str, dict[str, Any]]) -> tuple[ContestResult, Contest3Result | None]:
    """The contest's record and the three-behaviour task's (None where the run has none)."""
    three = stages.get(Contest3Stage.name)
    return (
        ContestStage.from_json(stages[ContestStage.name]),
        None if three is None else Contest3Stage.from_json(three),
    )


def _runs(contest: ContestResult, three: Contest3Result | None) -> dict[str, dict[str, ContestRun]]:
    """By rule (the three-behaviour task's among them, where the run has it), each contender's
    run as the report reads it."""
    runs = {**contest.runs, **(three.runs if three else {})}
    return {
        rule: {who: ContestRun.pick(d, f"contest {rule} {who}") for who, d in by.items()}
        for rule, by in runs.items()
    }


def claims(stages: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """One run cannot judge a claim about runs: the 2016 claim is stated with what this run
    measured and judged only over runs (``mbn sweep --experiment programs-vs-dynamics``)."""
    return _claims(_runs(*_records(stages)))


def _claims(runs: dict[str, dict[str, ContestRun]]) -> list[dict[str, Any]]:
    parts = []
    for rule, by in runs.items():
        parts.append(
            f"{rule}: " + ", ".join(f"{who} {d.evaluations_text}" for who, d in by.items())
        )
    return [
        {
            "claim": CLAIM_2016,
            "measured": "evaluations to test success in this run: " + "; ".join(parts),
            "target": f"over runs (`mbn sweep`): {CRITERION}",
            "pass": None,
        }
    ]


def _grown_text(three: Any) -> str:
    """What the grown contenders' first phase (right and left) cost, from the stage's record."""
    if three is None:
        return ""
    firsts = {
        who: d["two_rule_evaluations"]
        for who, d in three.runs.get(TASK, {}).items()
        if d.get("two_rule_evaluations") is not None
    }
    return "".join(
        f"; {who}'s first phase (right and left, two tile inputs) took {n} evaluations"
        for who, n in firsts.items()
    )


def _pm_text(runs: dict[str, dict[str, ContestRun]]) -> str:
    """What the MBN's program module cost (robot-free), where the run evolved one."""
    d = runs.get(TASK, {}).get("programs")
    if d is None or d.pm_evaluations is None:
        return ""
    return (
        f"; the MBN's program module took {d.pm_evaluations} evaluations without the robot "
        f"(program reward {d.pm_fitness:.4f})"
    )


def write_report(rundir: RunDir) -> None:
    """``report.md``, ``report.html`` and the checks figure."""
    from mbn.viz.contest import contest_checks
    from mbn.viz.runs import test_trajectories
    from mbn.world.mazes.load import load_maze

    run = RunResults.pick(read_json(rundir.results), str(rundir.results))
    stages = {name: rundir.read_stage(name) for name in run.stages}
    contest, three = _records(stages)
    recorded = {**contest.runs, **(three.runs if three else {})}
    runs = _runs(contest, three)
    tests = {**contest.tests, **(three.tests if three else {})}
    details = {**contest.details, **(three.details if three else {})}
    tally = {name: Tally.pick(t, f"test {name}") for name, t in tests.items()}
    file = "figures/contest.png"
    contest_checks(recorded, rundir.root / file)
    maze = load_maze(contest.mazes.test)
    pictures = []
    for rule, by in runs.items():
        trajectories = rundir.load_trajectories(f"contest_{rule}")
        for who in by:
            short = f"{who}_{rule.replace('-', '_')}"
            t = tally[short]
            picture = f"figures/contest_{rule}_{who}.png"
            test_trajectories(
                maze,
                trajectories[who],
                details[short],
                f"{who}, {rule}, final best in {maze.name}: {t.successes}/{t.trials}",
                rundir.root / picture,
            )
            pictures.append((picture, f"{rule}, {who}: the final best from each start mark"))
    rows = []
    for rule, by in runs.items():
        for who, d in by.items():
            short = f"{who}_{rule.replace('-', '_')}"
            cells = [rule, who, str(d.genes), d.evaluations_text, f"{d.best_fitness:.2f}"]
            for suffix in ("", "_jitter", "_heldout"):
                x = tally[f"{short}{suffix}"]
                cells.append(f"{x.successes}/{x.trials}")
            im = tally.get(f"im_{short}_jitter")
            cells.append("-" if im is None else f"{im.successes}/{im.trials}")
            rows.append(cells)
    secs = [
        Section(
            "What this run did",
            [
                f"Seed {run.seed}. Each new rule learned by each contender with the same "
                f"DE (population {contest.popsize}), the same crossroad episodes and the same "
                f"budget of {contest.budget} evaluations: "
                + "; ".join(f"**{k}**, {v}" for k, v in contest.contenders.items())
                + f". Every {contest.check_every} generations the best so far was tested on "
                f"{contest.mazes.test} (every start mark and the jittered starts): a dynamics "
                "contender's as its network, program search's "
                + checks_text([contest.program_checks])
                + "; "
                "its evaluations to success are those spent when it first passed "
                "(docs/contest.md). One run says little: the comparison is over runs "
                "(`mbn sweep --experiment programs-vs-dynamics`).",
            ],
        ),
        *(
            []
            if three is None
            else [
                Section(
                    "The three-behaviour task",
                    [
                        f"A controller that follows the rule of the last tile driven over "
                        f"({', '.join(three.tile_rules)} after a tile of 1, 2, 3 colours), "
                        "learned by: "
                        + "; ".join(f"**{k}**, {v}" for k, v in three.contenders.items())
                        + f". The same DE and budget ({three.budget} evaluations); each "
                        "check runs the whole controller on "
                        f"{three.mazes.test}, its junctions judged from the first tile. "
                        "Robot episodes per evaluation (with the perturbed copies): "
                        + ", ".join(f"{k} {v}" for k, v in three.episodes_per_evaluation.items())
                        + _pm_text(runs)
                        + _grown_text(three)
                        + ".",
                    ],
                )
            ]
        ),
        claims_section(_claims(runs)),
        Section(
            "Contenders",
            table=(
                [
                    "rule",
                    "contender",
                    "genes",
                    "evaluations to success",
                    "final fitness",
                    "marks",
                    "jittered",
                    f"held-out ({contest.mazes.heldout})",
                    "through the interpreter (jittered)",
                ],
                rows,
            ),
            images=[(file, "Best fitness per check; filled: the best then passed the test")],
        ),
        *_baselines_section(three, tally, contest.mazes.heldout),
        Section("Each contender's final best", images=pictures),
    ]
    write_document(rundir.root, "report", TITLE, secs)


def _baselines_section(three: Any, tally: dict[str, Tally], heldout: str) -> list[Section]:
    """The three-behaviour task's baselines (the oracle, the gate), beside the MBN: built from
    the programs contender's programs, tested as the finals are."""
    if three is None or not three.baselines:
        return []
    rows = []
    for who in ("programs", *three.baselines):
        short = f"{who}_{TASK.replace('-', '_')}"
        if short not in tally:
            continue
        what = "the MBN (interpreter and program module)" if who == "programs" else who
        cells = [what]
        for suffix in ("", "_jitter", "_heldout"):
            x = tally[f"{short}{suffix}"]
            cells.append(f"{x.successes}/{x.trials}")
        rows.append(cells)
    text = "; ".join(f"**{k}**: {v['what']}" for k, v in three.baselines.items())
    return [
        Section(
            "The MBN against its baselines (three behaviours)",
            [
                "The same three programs, run three ways: by the MBN, and by two baselines "
                f"with no search of their own ({text}). Where the oracle passes and the MBN "
                "does not, the multipliers or the program module cost it."
            ],
            table=(["controller", "marks", "jittered", f"held-out ({heldout})"], rows),
        )
    ]
