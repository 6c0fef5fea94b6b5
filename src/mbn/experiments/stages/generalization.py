"""Stage ``generalization``: the run's controllers judged in mazes drawn from their family -
train, validation and **test** splits side by side - and on the zero-shot suite
(``docs/generalization.md``).

Nothing here chooses anything: the stage runs after every controller is made and only judges
them. Each controller is judged on its family (``grid`` for the followers, the interpreter and
the programs; the family of its tile kinds for an MBN: ``tiles2``, ``tiles3``):

- ``train``: the first ``gap_mazes`` mazes the run's maze episodes were drawn from (its pool) where
  it evolved on that family's maze episodes, else the first ``gap_mazes`` of the train split;
- ``validation``: the first ``gap_mazes`` of the validation split (the first ``[validation]
  split_mazes`` of them chose among candidates in a run on maze episodes);
- ``test``: the first ``test_mazes`` of the test split, which no stage, setting or default is
  chosen on;
- ``zero-shot``: the family's part of the hand-made zero-shot suite.

``[generalization] splits`` names the columns judged: a development run leaves out ``test``
and ``zero-shot``, so that whoever tunes on it never sees them.

Every start mark of every maze, ``repeats`` times (the first from the mark, the others jittered
by the run's ``test_jitter`` seed), three junctions judged; a controller's mazes run in two
batches, the generated splits' and the zero-shot suite's, each under the longest of its mazes'
own time limits (``[generalization] zero_shot_batch``; the quick preset: one batch).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from mbn.config import Settings, setting
from mbn.controllers import make_controller, read_controller_spec
from mbn.errors import MbnInputError
from mbn.experiments.generalization import (
    GeneralizationResult,
    JudgedRecord,
    SplitRecord,
    WorstMaze,
    evaluate_mazes,
    meets_generalization,
    pooled_rows,
    split_record,
)
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.stages.common import (
    maze_episodes,
    noise_key,
    run_noise,
    tile_family,
)
from mbn.experiments.stages.keys import KEYS
from mbn.experiments.trials import TrialSpec

__all__ = [
    "REPRODUCE_JUDGED",
    "GeneralizationResult",
    "GeneralizationSettings",
    "GeneralizationStage",
    "Judged",
    "ReproduceGeneralization",
]

#: Folded into the stage's key for the noise of its trials (no generation index reaches it).
GENERALIZATION_NOISE_KEY = 10**6 + 4
#: The record of the worst test maze's trials, and the fields of their trajectories kept.
WORST_RECORD = "generalization_worst"
WORST_FIELDS = ("t", "pose", "stalled")
#: The splits of a controller's record, in the order the report shows them.
SPLIT_ORDER = ("train", "validation", "test", "zero-shot")


@dataclass(frozen=True)
class GeneralizationSettings(Settings):
    """How the run's controllers are judged in mazes drawn from their family (no choice is made
    on them)."""

    section = "generalization"
    # runs recorded before ``zero_shot_batch`` judged every maze in one batch
    recorded_before: ClassVar[dict[str, Any]] = {"zero_shot_batch": False}
    test_mazes: int = setting(
        100,
        doc="mazes of the test split each controller is judged in (its first N)",
        low=1,
        high=100,
        source="docs/generalization.md (a test split of 100 mazes)",
    )
    gap_mazes: int = setting(
        50,
        doc="mazes of the train and of the validation split judged beside the test split (the "
        "generalization gap; 0: neither)",
        low=0,
        high=100,
        source="docs/generalization.md (50: the gap's two columns at 500 trials each, a third "
        "of the judging less than 100)",
    )
    splits: tuple[str, ...] = setting(
        SPLIT_ORDER,
        doc="the columns judged (a development run may leave out the test split and the "
        "zero-shot suite, so that nothing tuned on it has seen them)",
        choices=SPLIT_ORDER,
        source="docs/generalization.md",
    )
    zero_shot_batch: bool = setting(
        True,
        doc="judge the zero-shot suite in a batch of its own, under the longest of its mazes' "
        "time limits (up to 370 s; the generated mazes' about 115 s, at most 270 s): fewer "
        "robot-steps, a compilation more per controller kind (false: every maze in one batch "
        "under the longest limit of all)",
        source="docs/generalization.md (Cost)",
    )
    worst_maze: bool = setting(
        True,
        doc="run the test maze with the fewest successes again, every other step recorded, for "
        "the report's picture of its trials",
        source="docs/generalization.md",
    )
    repeats: int = setting(
        1,
        doc="trials per start mark (the mark, then jittered starts)",
        low=1,
        high=100,
        source="as mbn evaluate (one trial per start mark)",
    )


@dataclass(frozen=True)
class Judged:
    """One controller the stage judges: its name in the record, its file (``controllers/
    FILE.json``), the behaviour it is judged as, the stored program it runs and the family it is
    judged in (default: ``grid``, or for an MBN the family of its tile kinds)."""

    name: str
    file: str
    behavior: str
    program: str | None = None
    family: str | None = None


#: The reproduction's controllers.
REPRODUCE_JUDGED = (
    Judged("rf", "rf", "right"),
    Judged("lf", "lf", "left"),
    Judged("im_rf", "im", "right", "right"),
    Judged("im_lf", "im", "left", "left"),
    Judged("mbn", "mbn", "tiles"),
)


def split_mazes(ctx: StageContext, family: str, split: str, count: int) -> tuple[list[Any], bool]:
    """The mazes of one column and whether the run evolved on them (``train`` only)."""
    from mbn.experiments.maze_task import MazeTask
    from mbn.world.mazes import families
    from mbn.world.mazes.load import builtin_maze

    if split == "zero-shot":
        return [builtin_maze(n) for n in families.ZERO_SHOT.get(family, ())], False
    episodes = maze_episodes(ctx)
    if split == "train" and episodes is not None and episodes.family == family:
        task = MazeTask(family=family, pool=episodes.pool, seed=ctx.seeds["crossroad_jitter"])
        seeds = task.pool_seeds()[:count]
        return [families.generate(family, s) for s in seeds], True
    seeds = families.split_seeds(split, 0, count - 1, family)
    return [families.generate(family, s) for s in seeds], False


def judging_batches(
    parts: list[tuple[str, list[Any], bool]], zero_shot_batch: bool
) -> list[list[tuple[str, list[Any], bool]]]:
    """The batches a controller's columns (``(split, mazes, seen)``, in order) are judged in:
    the generated splits' together and the zero-shot suite apart (``zero_shot_batch``; each
    batch runs under the longest of its own mazes' time limits), else all in one; no empty
    batch."""
    if not zero_shot_batch:
        return [parts] if parts else []
    generated = [p for p in parts if p[0] != "zero-shot"]
    zero = [p for p in parts if p[0] == "zero-shot"]
    return [b for b in (generated, zero) if b]


def _worst_maze(
    mazes: list[Any], result: dict[str, Any], trial: TrialSpec, loaded: Any, key: Any
) -> tuple[Any, Any, WorstMaze]:
    """The test maze with the fewest successes (the first of equals) run again, every other
    step recorded, for the report's picture of its failed trials: ``(maze, trajectory,
    record)``, the record naming the maze and each trial's verdict."""
    import jax

    from mbn.experiments.trials import TrialGroup, run_trial_groups, verdict_details

    rates = [r["success_rate"] for r in result["mazes"]]
    m = int(np.argmin(rates))
    maze = mazes[m]
    spec = dataclasses.replace(trial, seconds=result["seconds"])
    verdicts, rollout, slices, _ = run_trial_groups(
        [maze],
        [TrialGroup("worst", 0, spec, loaded.initial_state)],
        loaded.controller,
        seconds=result["seconds"],
        dt=loaded.dt,
        sensors=loaded.sensors,
        camera=loaded.camera,
        record_every=2,
        noise=loaded.noise,
        key=key,
    )
    v = verdicts["worst"]
    trajectory = jax.tree.map(lambda a: np.asarray(a)[slices["worst"]], rollout.trajectory)
    record = WorstMaze(maze=maze.name, success_rate=rates[m], details=verdict_details(v))
    return maze, trajectory, record


class GeneralizationStage(Stage[GeneralizationResult]):
    """The stage of an experiment: a subclass names the controllers it judges (``judged``), the
    stages that make them (``needs``) and its key."""

    name = "generalization"
    settings = GeneralizationSettings
    judged: ClassVar[tuple[Judged, ...]] = ()

    def controllers(self, ctx: StageContext) -> tuple[Judged, ...]:
        """The controllers judged (default: ``judged``)."""
        return self.judged

    result = GeneralizationResult

    def run(self, ctx: StageContext) -> GeneralizationResult:
        s: GeneralizationSettings = ctx.settings
        counts = {"train": s.gap_mazes, "validation": s.gap_mazes, "test": s.test_mazes}
        out: dict[str, JudgedRecord] = {}
        # under the run's noise, as its tests (its own stream)
        noise = run_noise(ctx)
        key = noise_key(ctx, GENERALIZATION_NOISE_KEY)
        worst: dict[str, tuple[Any, Any, WorstMaze]] = {}
        for j in self.controllers(ctx):
            spec = read_controller_spec(ctx.rundir.controller_file(j.file))
            loaded = make_controller(
                spec,
                j.program,
                where=f"generalization ({j.name})",
                check_stability=False,
                noise=noise,
            )
            tile_rules = tuple(loaded.tile_rules or ("right", "left"))
            family = j.family or (tile_family(tile_rules) if j.behavior == "tiles" else "grid")
            initial = (loaded.initial_rule or "right") if j.behavior == "tiles" else "right"
            trial = TrialSpec(
                behavior=j.behavior,
                initial=initial,
                repeats=s.repeats,
                seed=ctx.seeds["test_jitter"],
                tile_rules=tile_rules,
            )
            parts: list[tuple[str, list[Any], bool]] = []
            for split in SPLIT_ORDER:
                count = counts.get(split, 0)
                wanted = split in s.splits and (split == "zero-shot" or count > 0)
                if wanted:
                    parts.append((split, *split_mazes(ctx, family, split, count)))
            # two batches ([generalization] zero_shot_batch): the generated splits' mazes, then
            # the zero-shot suite, each under the longest of its own mazes' time limits (a
            # zero-shot maze needs up to 370 s, a generated one about 115 s): one compiled
            # rollout per controller kind and batch
            judged_by_split: dict[str, dict[str, Any]] = {}
            for batch in judging_batches(parts, s.zero_shot_batch):
                every = [m for _, mazes, _ in batch for m in mazes]
                judged = evaluate_mazes(every, trial, loaded, key=key, verdicts=True)
                start = 0
                for split, mazes, _ in batch:
                    judged_by_split[split] = {
                        "mazes": judged["mazes"][start : start + len(mazes)],
                        "seconds": judged["seconds"],
                        "verdicts": {m.name: judged["verdicts"][m.name] for m in mazes},
                    }
                    start += len(mazes)
            splits: dict[str, SplitRecord] = {}
            for split, mazes, seen in parts:
                one = judged_by_split[split]
                rows = one["mazes"]
                result = {
                    "mazes": rows,
                    **pooled_rows(rows),
                    "seconds": one["seconds"],
                    "verdicts": one["verdicts"],
                }
                splits[split] = split_record(
                    result,
                    breakdown=split in ("test", "zero-shot"),
                    mazes=mazes if j.behavior == "tiles" else None,
                    seen_in_training=seen,
                )
                if split == "test" and s.worst_maze:
                    worst[j.name] = _worst_maze(mazes, result, trial, loaded, key)
            out[j.name] = JudgedRecord(
                file=f"controllers/{j.file}.json",
                behavior=j.behavior,
                program=j.program,
                family=family,
                splits=splits,
                worst_test_maze=worst[j.name][2] if j.name in worst else None,
            )
        if worst:
            trajectories = {name: w[1] for name, w in worst.items()}
            ctx.rundir.save_trajectories(WORST_RECORD, trajectories, WORST_FIELDS)
        return GeneralizationResult(
            controllers=out, noise=noise.as_dict() if noise.enabled else None
        )

    def metrics(self, data: dict[str, Any]) -> dict[str, Any]:
        return data

    def summary(self, result: GeneralizationResult) -> str:
        parts = []
        for name, rec in result.controllers.items():
            test = rec.splits.get("test")
            if test is None:
                continue
            parts.append(
                f"{name} {test.pooled.success_rate:.1%} ({test.mazes_at_95}/"
                f"{len(test.mazes)})" + ("" if meets_generalization(test) else " x")
            )
        return "test split: " + ", ".join(parts)


class ReproduceGeneralization(GeneralizationStage):
    """``mbn reproduce``'s: RF, LF, the interpreter with each program, the MBN."""

    key_id = KEYS["generalization"]
    needs = ("rf", "lf", "im", "pm")
    judged = REPRODUCE_JUDGED


def _rate(record: SplitRecord) -> str:
    p = record.pooled
    lo, hi = p.wilson95
    return f"{p.successes}/{p.trials} = {p.success_rate:.1%} [{lo:.1%}, {hi:.1%}]"


def generalization_sections(rundir: Any, data: GeneralizationResult | dict[str, Any]) -> list[Any]:
    """The report's sections of a ``generalization`` stage's result (its record or its JSON,
    as ``results.json`` keeps it): the splits side by side
    (the generalization gap), the performance profile on the test split, where the misses are
    (causes, junction kinds) and the worst test maze's trials. Figures go to ``figures/``."""
    from mbn.experiments.pipeline.document import Section
    from mbn.viz.generalization import performance_profile
    from mbn.viz.runs import test_trajectories
    from mbn.world.mazes.load import load_maze

    result = data if isinstance(data, GeneralizationResult) else GeneralizationResult.pick(data)
    controllers = result.controllers
    rows, status = [], []
    for name, rec in controllers.items():
        for split in SPLIT_ORDER:
            r = rec.splits.get(split)
            if r is None:
                continue
            f = r.failures
            rows.append(
                [
                    name,
                    f"{rec.family}/{split}" + (" (seen)" if r.seen_in_training else ""),
                    _rate(r),
                    f"{r.mazes_at_95}/{len(r.mazes)}",
                    f"{f.wrong_exit} / {f.stalled} / {f.timed_out}",
                    ("yes" if r.meets_targets else "no") if split == "test" else "-",
                ]
            )
            status.append(r.meets_targets if split == "test" else None)
    sections = [
        Section(
            "Generalization: mazes drawn from the family",
            [
                "Each controller judged in mazes of its family (`grid` for the followers and the "
                "programs, the family of its tile kinds for an MBN): the train split (the mazes "
                "its episodes were drawn from, marked *seen*, where it evolved on that family), "
                "the validation split (its first mazes chose among candidates in a run on maze "
                "episodes), the **test split**, which nothing in any run is chosen on, and the "
                "hand-made zero-shot suite. Every start mark of every maze, three junctions "
                "judged. Targets on the test split: pooled success at least 95 % and at least "
                "90 % of the mazes each at 95 % (`docs/generalization.md`). Pooled rates with "
                "their Wilson 95 % interval; failures by cause (wrong exit / stalled / timed "
                "out)."
            ],
            table=(
                ["controller", "mazes", "pooled success", "mazes at >= 95 %", "failures", "meets"],
                rows,
            ),
            status=status,
        )
    ]
    curves = {
        name: [m.successes / m.trials for m in rec.splits["test"].mazes]
        for name, rec in controllers.items()
        if "test" in rec.splits
    }
    images = []
    if curves:
        file = "figures/generalization_profile.png"
        performance_profile(curves, rundir.root / file, "test split: performance profile")
        images.append((file, "Fraction of the test mazes at a success rate of at least x"))
    kinds: dict[str, dict[str, str]] = {}
    for name, rec in controllers.items():
        test = rec.splits.get("test")
        for kind, k in ((test and test.junction_kinds) or {}).items():
            kinds.setdefault(kind, {})[name] = f"{k.correct}/{k.passes}"
    names = list(controllers)
    sections.append(
        Section(
            "Generalization: where the misses are",
            [
                "Judged junction passes on the test split taken by the rule in force, by the "
                "junction's kind (the exits open as the robot enters it)."
            ],
            table=(
                ["junction", *names],
                [[k] + [v.get(n, "-") for n in names] for k, v in kinds.items()],
            ),
            images=images,
        )
    )
    distances: dict[str, dict[str, str]] = {}
    for name, rec in controllers.items():
        test = rec.splits.get("test")
        for d, k in ((test and test.tile_distances) or {}).items():
            stalled = k.stall_fraction
            distances.setdefault(d, {})[name] = f"{k.correct}/{k.passes}" + (
                "" if stalled is None else f" ({stalled:.1%} stalled)"
            )
    if distances:
        tiled = [n for n in names if any(n in v for v in distances.values())]
        sections.append(
            Section(
                "Generalization: the tile's distance before the junction",
                [
                    "An MBN's judged junction passes on the test split taken by the rule in "
                    "force, by how many free cells lay between the nearest tile in the corridor "
                    "it came along and the junction (turn: the tile lay on the corner that "
                    "corridor began at; none: no tile in that corridor), and the share of the "
                    "robot's moves from the pass before to this one that stalled."
                ],
                table=(
                    ["tile cells before", *tiled],
                    [[d, *(v.get(n, "-") for n in tiled)] for d, v in distances.items()],
                ),
            )
        )
    worst_images = []
    try:
        trajectories = rundir.load_trajectories(WORST_RECORD)
    except MbnInputError:  # no record: a run made before it existed
        trajectories = {}
    for name, rec in controllers.items():
        w = rec.worst_test_maze
        if w is None or name not in trajectories:
            continue
        maze = load_maze(w.maze)
        file = f"figures/generalization_worst_{name}.png"
        details = w.details
        won = details["success"]  # the verdicts' fields (trials.verdict_details)
        test_trajectories(
            maze,
            trajectories[name],
            details,
            f"{name}: worst test maze {maze.name}: {sum(won)}/{len(won)}",
            rundir.root / file,
        )
        worst_images.append((file, f"{name}: the worst test maze, one panel per trial"))
    if worst_images:
        sections.append(
            Section(
                "Generalization: the worst test maze",
                [
                    "For each controller, the test maze with the fewest successes, its trials "
                    "run again with every other step recorded (red: stalled steps)."
                ],
                images=worst_images,
            )
        )
    return sections
