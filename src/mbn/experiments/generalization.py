"""Judging a controller across many mazes at once: a split of a maze family, the zero-shot
suite (``docs/generalization.md``).

:func:`evaluate_mazes` runs every maze's trials in one batched rollout under one time limit (the
longest of the mazes' own, unless given; each trial stops once judged,
:mod:`mbn.world.judged`) and gives one row per maze and the pooled figures;
``mbn evaluate --maze FAMILY/SPLIT`` prints it, and the runs' generalization sections are made
of it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
from jax import Array

from mbn.experiments.pipeline.results import Record, keyed, optional
from mbn.experiments.trials import (
    MAX_STALL_FRACTION,
    TrialGroup,
    TrialSpec,
    join_verdicts,
    route_seconds,
    run_trial_groups,
    summary,
)
from mbn.stats import performance_profile, wilson_interval
from mbn.world.rules import OPEN_BITS

__all__ = [
    "MAZE_TARGET",
    "Failures",
    "GeneralizationClaim",
    "GeneralizationResult",
    "JudgedRecord",
    "MazeRow",
    "Passes",
    "Pooled",
    "SplitRecord",
    "evaluate_mazes",
    "failure_causes",
    "generalization_claims",
    "junction_kind",
    "junction_kinds",
    "meets_generalization",
    "performance_profile",
    "pooled_rows",
    "split_record",
    "tile_distance",
    "tile_distances",
]

#: A maze counts as passed when at least this share of its trials succeed (the tests' target).
MAZE_TARGET = 0.95
#: The generalization targets on a test split: pooled success, and the share of the mazes that
#: pass (each at :data:`MAZE_TARGET`).
POOLED_TARGET = 0.95
MAZE_SHARE_TARGET = 0.90


@dataclass(frozen=True, kw_only=True)
class MazeRow(Record):
    """One maze of a split: its trials, successes and time-outs."""

    maze: str
    trials: int
    successes: int
    timed_out: int

    @property
    def rate(self) -> float:
        """Its success rate (0 without trials)."""
        return self.successes / self.trials if self.trials else 0.0


@dataclass(frozen=True, kw_only=True)
class Pooled(Record):
    """A split's trials pooled over its mazes, with the Wilson 95 % interval of the rate."""

    trials: int
    successes: int
    timed_out: int
    success_rate: float
    wilson95: list[float]


@dataclass(frozen=True, kw_only=True)
class Failures(Record):
    """A split's failed trials by cause: the first wrong exit, else stalled, else timed out."""

    failed: int
    wrong_exit: int
    stalled: int
    timed_out: int


@dataclass(frozen=True, kw_only=True)
class Passes(Record):
    """Judged junction passes and how many took the rule's exit; by the tile's distance, also
    the robot-steps of the stretches that led to them and how many of those were stalled moves
    (None where not recorded: junction kinds, and runs made before)."""

    passes: int
    correct: int
    steps: int | None = optional()
    stalled: int | None = optional()

    @property
    def stall_fraction(self) -> float | None:
        """The stalled share of the stretches' steps (None where not recorded)."""
        if self.steps is None or self.stalled is None or not self.steps:
            return None
        return self.stalled / self.steps


@dataclass(frozen=True, kw_only=True)
class SplitRecord(Record):
    """What a run records of one split (:func:`split_record`): the mazes, the pooled trials,
    how many mazes reach :data:`MAZE_TARGET`, the batch's time limit, the failures' causes,
    whether the generalization targets are met, and, on the test split and the zero-shot suite,
    the passes by junction kind and (an MBN's) by the tile's distance before the junction;
    whether its mazes were those the controller's episodes were drawn from."""

    mazes: list[MazeRow]
    pooled: Pooled
    mazes_at_95: int
    fraction_of_mazes_at_95: float
    seconds: float
    failures: Failures
    meets_targets: bool
    junction_kinds: dict[str, Passes] | None = optional()
    tile_distances: dict[str, Passes] | None = optional()
    seen_in_training: bool | None = optional()


@dataclass(frozen=True, kw_only=True)
class WorstMaze(Record):
    """A controller's worst test maze: its name, success rate and the details of its trials
    (run again recording their trajectories)."""

    maze: str
    success_rate: float
    details: dict[str, Any]


@dataclass(frozen=True, kw_only=True)
class JudgedRecord(Record):
    """One controller judged across mazes: its file, behaviour, program and family, its splits'
    records (``train``, ``validation``, ``test``, ``zero-shot``) and its worst test maze."""

    file: str
    behavior: str
    program: str | None
    family: str
    splits: dict[str, SplitRecord]
    worst_test_maze: WorstMaze | None = optional()


@dataclass(frozen=True, kw_only=True)
class GeneralizationResult(Record):
    """What a ``generalization`` stage records (``stages/generalization.json``): by
    controller, its :class:`JudgedRecord`, and the noise the trials ran under (None: none)."""

    controllers: dict[str, JudgedRecord]
    noise: dict[str, Any] | None


def pooled_rows(rows: list[dict[str, Any]], target: float = MAZE_TARGET) -> dict[str, Any]:
    """The pooled trials, successes, time-outs and rate of per-maze rows, and how many of the
    mazes reach ``target``."""
    pooled: dict[str, Any] = {
        k: int(sum(r[k] for r in rows)) for k in ("trials", "successes", "timed_out")
    }
    pooled["success_rate"] = pooled["successes"] / pooled["trials"] if pooled["trials"] else 0.0
    at = sum(r["success_rate"] >= target for r in rows)
    return {
        "pooled": pooled,
        "mazes_at_95": int(at),
        "fraction_of_mazes_at_95": at / len(rows) if rows else 0.0,
    }


def evaluate_mazes(
    mazes: list[Any],
    spec: TrialSpec,
    loaded: Any,
    *,
    seconds: float | None = None,
    key: Array | None = None,
    verdicts: bool = False,
) -> dict[str, Any]:
    """Every maze's trials of ``spec`` for the loaded controller ``loaded``, in one batch.

    Returns ``{"mazes": [{"maze", ...summary}], "pooled", "mazes_at_95",
    "fraction_of_mazes_at_95", "seconds"}`` (and, ``verdicts``, each maze's verdict arrays under
    ``"verdicts"``, by maze name, not JSON). ``seconds``: the time limit (default the longest of
    the mazes' own, :func:`~mbn.experiments.trials.route_seconds`); ``key``: the noise's key
    (when the controller runs under noise)."""
    if not mazes:
        raise ValueError("evaluate_mazes needs at least one maze")
    names = [m.name for m in mazes]
    if len(set(names)) != len(names):
        raise ValueError("evaluate_mazes needs mazes of distinct names")
    if seconds is None:
        seconds = max(route_seconds(m, spec) for m in mazes)
    spec = dataclasses.replace(spec, seconds=seconds)
    camera = loaded.camera
    if camera is None and spec.behavior == "tiles":
        from mbn.world.engine import CameraConfig

        camera = CameraConfig()
    out, _, _, _ = run_trial_groups(
        mazes,
        [TrialGroup(m.name, i, spec, loaded.initial_state) for i, m in enumerate(mazes)],
        loaded.controller,
        seconds=seconds,
        dt=loaded.dt,
        sensors=loaded.sensors,
        camera=camera,
        noise=loaded.noise,
        key=key,
        until_judged=True,
    )
    rows = [{"maze": m.name, **summary(out[m.name])} for m in mazes]
    result: dict[str, Any] = {"mazes": rows, **pooled_rows(rows), "seconds": float(seconds)}
    if verdicts:
        result["verdicts"] = {n: {k: np.asarray(v) for k, v in out[n].items()} for n in names}
    return result


def junction_kind(mask: int) -> str:
    """A junction's kind by the exits open as the robot enters it (an
    :data:`~mbn.world.rules.OPEN_BITS` mask): ``plus``, ``T left-right``, ``T straight-right``,
    ``T straight-left``, or ``corner right`` / ``corner left`` / ``straight`` with one exit."""
    exits = [e for e in ("left", "straight", "right") if mask & OPEN_BITS[e]]
    if len(exits) == 3:
        return "plus"
    if len(exits) == 2:
        return "T " + "-".join(exits)
    if len(exits) == 1:
        return exits[0] if exits[0] == "straight" else f"corner {exits[0]}"
    return "dead end"


def junction_kinds(verdict: dict[str, np.ndarray]) -> dict[str, dict[str, int]]:
    """Every judged junction pass of a verdict by the junction's kind (:func:`junction_kind`):
    ``{kind: {"passes", "correct"}}``, kinds in a fixed order."""
    opened = np.asarray(verdict["open"]).ravel()
    right = (np.asarray(verdict["exits"]) == np.asarray(verdict["expected"])).ravel()
    out: dict[str, dict[str, int]] = {}
    for mask in sorted(set(int(m) for m in opened if m >= 0)):
        here = opened == mask
        kind = junction_kind(mask)
        row = out.setdefault(kind, {"passes": 0, "correct": 0})
        row["passes"] += int(here.sum())
        row["correct"] += int((here & right).sum())
    return out


def failure_causes(verdict: dict[str, np.ndarray]) -> dict[str, int]:
    """Why the failed trials of a verdict failed, each counted once in this order: ``wrong_exit``
    (a judged junction left by another exit than the rule's), ``stalled`` (stall fraction over
    :data:`~mbn.experiments.trials.MAX_STALL_FRACTION`), ``timed_out`` (the time limit ended
    it first)."""
    success = np.asarray(verdict["success"], bool)
    wrong = np.asarray(verdict["correct"]) < np.asarray(verdict["judged"])
    stalled = np.asarray(verdict["stall"]) > MAX_STALL_FRACTION
    failed = ~success
    return {
        "failed": int(failed.sum()),
        "wrong_exit": int((failed & wrong).sum()),
        "stalled": int((failed & ~wrong & stalled).sum()),
        "timed_out": int((failed & ~wrong & ~stalled).sum()),
    }


def meets_generalization(record: SplitRecord | dict[str, Any]) -> bool:
    """Whether a split's record meets the generalization targets: pooled success at least
    :data:`POOLED_TARGET` and at least :data:`MAZE_SHARE_TARGET` of its mazes each at
    :data:`MAZE_TARGET` (compared as fractions of whole trials and mazes)."""
    rec = record if isinstance(record, SplitRecord) else SplitRecord.pick(record)
    return _meets(rec.pooled.successes, rec.pooled.trials, rec.mazes_at_95, len(rec.mazes))


def _meets(successes: int, trials: int, mazes_at_95: int, mazes: int) -> bool:
    return bool(
        successes * 100 >= round(POOLED_TARGET * 100) * trials
        and mazes_at_95 * 100 >= round(MAZE_SHARE_TARGET * 100) * mazes
    )


def split_record(
    result: dict[str, Any],
    *,
    breakdown: bool = False,
    mazes: list[Any] | None = None,
    seen_in_training: bool | None = None,
) -> SplitRecord:
    """What a run records of :func:`evaluate_mazes` (called with ``verdicts``) on one split:
    the per-maze rows (maze, trials, successes, timed out), the pooled figures with their
    Wilson 95 % interval, how many mazes pass, the failures' causes, whether the
    generalization targets are met, and, ``breakdown``, the judged passes by junction kind (and,
    given the split's ``mazes`` with tiles, by the tile's distance before the junction)."""
    verdicts = result["verdicts"]
    joined = join_verdicts(list(verdicts.values()))
    pooled = result["pooled"]
    lo, hi = wilson_interval(pooled["successes"], pooled["trials"])
    rows = [MazeRow.pick(r) for r in result["mazes"]]
    tiles = breakdown and mazes is not None and any(m.tiles for m in mazes)
    return SplitRecord(
        mazes=rows,
        pooled=Pooled.from_json({**pooled, "wilson95": [lo, hi]}),
        mazes_at_95=result["mazes_at_95"],
        fraction_of_mazes_at_95=result["fraction_of_mazes_at_95"],
        seconds=result["seconds"],
        failures=Failures.from_json(failure_causes(joined)),
        meets_targets=_meets(
            pooled["successes"], pooled["trials"], result["mazes_at_95"], len(rows)
        ),
        junction_kinds=(
            {k: Passes.from_json(v) for k, v in junction_kinds(joined).items()}
            if breakdown
            else None
        ),
        tile_distances=(
            {k: Passes.from_json(v) for k, v in tile_distances(mazes or [], verdicts).items()}
            if tiles
            else None
        ),
        seen_in_training=seen_in_training,
    )


@dataclass(frozen=True, kw_only=True)
class GeneralizationClaim(Record):
    """A claims row of a ``generalization`` stage (:func:`generalization_claims`)."""

    claim: str
    paper: str
    measured: str
    target: str
    passed: bool = keyed("pass")


def generalization_claims(data: Any) -> list[GeneralizationClaim]:
    """The claims rows of a ``generalization`` stage's result (its record,
    :class:`GeneralizationResult`, or its JSON; None:
    no rows): for each controller, "holds in mazes drawn from its family, never looked into"
    (its test split: the targets of :func:`meets_generalization`), with the zero-shot suite's
    pooled rate beside it."""
    if not data:
        return []
    result = data if isinstance(data, GeneralizationResult) else GeneralizationResult.pick(data)
    rows = []
    for name, rec in result.controllers.items():
        test = rec.splits.get("test")
        if test is None:
            continue
        p = test.pooled
        zs = rec.splits.get("zero-shot")
        zero = (
            f"; zero-shot suite {zs.pooled.successes}/{zs.pooled.trials} "
            f"({zs.pooled.success_rate:.1%})"
            if zs
            else ""
        )
        rows.append(
            GeneralizationClaim(
                claim=f"{name} holds in mazes drawn from the {rec.family} family, never "
                "looked into (its test split)",
                paper="not tested in the paper (its tests: one maze)",
                measured=f"{p.successes}/{p.trials} ({p.success_rate:.1%}) pooled "
                f"over {len(test.mazes)} test mazes, {test.mazes_at_95} of them at >= 95 %" + zero,
                target=f"pooled >= {POOLED_TARGET:.0%} and >= {MAZE_SHARE_TARGET:.0%} of the "
                f"mazes at >= {MAZE_TARGET:.0%}",
                passed=meets_generalization(test),
            )
        )
    return rows


#: Tiles further than this before a junction are counted together ("4+").
_FAR = 4


def tile_distance(maze: Any, cell: tuple[int, int], heading: int) -> int | str | None:
    """How many free cells lie between a junction pass's cell and the nearest tile in the
    corridor the robot came along (entering ``cell`` by ``heading``: 0..3 = N, E, S, W): 0 for
    a tile in the cell just before it; ``"turn"`` where the nearest tile lies on the corner
    that corridor begins at (the program switched in the middle of the turn); None where no
    tile lies in that corridor before its previous junction or corner."""
    from mbn.world.junctions import STEPS, cell_of

    grid = np.asarray(maze.grid) != "#"
    rows, cols = grid.shape

    def free(r: int, c: int) -> bool:
        return 0 <= r < rows and 0 <= c < cols and bool(grid[r, c])

    tiles = {cell_of(maze, t.x, t.y) for t in maze.tiles}
    dr, dc = STEPS[heading]
    r, c = cell[0] - dr, cell[1] - dc  # the cell it came from
    k = 0
    while free(r, c):
        neighbours = sum(free(r + a, c + b) for a, b in STEPS)
        straight = neighbours == 2 and free(r + dr, c + dc) and free(r - dr, c - dc)
        if (r, c) in tiles:
            return k if straight or neighbours != 2 else "turn"
        # on along the corridor only through a straight cell (two free neighbours, in line)
        if not straight:
            return None
        r, c = r - dr, c - dc
        k += 1
    return None


def tile_distances(mazes: list[Any], verdicts: dict[str, dict[str, np.ndarray]]) -> dict[str, Any]:
    """Every judged junction pass of an MBN's trials by how far before it the nearest tile lay
    in the corridor it came along (:func:`tile_distance`: ``"0"`` .. ``"3"``, ``"4+"``,
    ``"turn"`` or ``"none"``): ``{distance: {"passes", "correct"}}``, and where the verdicts
    record the stretches before each pass (``stretch_steps``, ``stretch_stalls``), their
    ``steps`` and ``stalled`` moves. ``verdicts``: each maze's verdict (with ``cells`` and
    ``headings``), by maze name."""
    out: dict[str, dict[str, int]] = {}
    keys = [str(k) for k in range(_FAR)] + [f"{_FAR}+", "turn", "none"]
    for maze in mazes:
        v = verdicts[maze.name]
        cells, headings = np.asarray(v["cells"]), np.asarray(v["headings"])
        right = np.asarray(v["exits"]) == np.asarray(v["expected"])
        stretch = (
            (np.asarray(v["stretch_steps"]), np.asarray(v["stretch_stalls"]))
            if "stretch_steps" in v
            else None
        )
        memo: dict[tuple[int, int, int], int | str | None] = {}
        for idx in zip(*np.nonzero(headings >= 0), strict=True):
            r, c = (int(x) for x in cells[idx])
            h = int(headings[idx])
            if (r, c, h) not in memo:
                memo[(r, c, h)] = tile_distance(maze, (r, c), h)
            d = memo[(r, c, h)]
            if d is None or isinstance(d, str):
                key = "none" if d is None else d
            else:
                key = str(d) if d < _FAR else f"{_FAR}+"
            row = out.setdefault(key, {"passes": 0, "correct": 0})
            row["passes"] += 1
            row["correct"] += int(right[idx])
            if stretch is not None:
                row["steps"] = row.get("steps", 0) + int(stretch[0][idx])
                row["stalled"] = row.get("stalled", 0) + int(stretch[1][idx])
    return {k: out[k] for k in keys if k in out}
