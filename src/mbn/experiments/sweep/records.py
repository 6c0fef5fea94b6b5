"""The sweep's own file, ``sweep.json``, as its report reads it: typed views
(:class:`~mbn.experiments.pipeline.results.Record`) of the statistics
:func:`~mbn.experiments.sweep.summary.summarize` writes (``summary``) and of the sweep's
settings and runs. Read with :meth:`~mbn.experiments.pipeline.results.Record.pick` where the
file holds more than the report reads (a run's worker, the sweep's executor)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from mbn.experiments.pipeline.results import Record, keyed

__all__ = [
    "ClaimOverRuns",
    "Pooled",
    "PooledTests",
    "ReuseEntry",
    "ReusedStages",
    "RunEntry",
    "SeedState",
    "SweepFile",
    "SweepHead",
    "SweepSettingsRecord",
    "SweepSummary",
    "TargetOverSeeds",
    "TestOverSeeds",
]


@dataclass(frozen=True, kw_only=True)
class Pooled(Record):
    """Every seed's trials pooled: hits (a test's successes, an agreement's same branches) of
    trials with the Wilson 95 % interval of the rate (NaN, null in the file, without trials)."""

    hits: int
    trials: int
    wilson95: list[float | None]


@dataclass(frozen=True, kw_only=True)
class PooledTests(Record):
    """A test's trials pooled over the seeds, with the Wilson 95 % interval of the rate."""

    successes: int
    trials: int
    wilson95: list[float | None]


@dataclass(frozen=True, kw_only=True)
class _Spread(Record):
    """The per-seed rates and their median, quartiles, min and max (NaN without seeds, which
    the file holds as null, as a rate without trials)."""

    rates: list[float | None]
    median: float | None
    q1: float | None
    q3: float | None
    min: float | None
    max: float | None


@dataclass(frozen=True, kw_only=True)
class TestOverSeeds(_Spread):
    """One test over the seeds: its rates' spread and its pooled trials."""

    pooled: PooledTests


@dataclass(frozen=True, kw_only=True)
class TargetOverSeeds(_Spread):
    """One per-run target over the seeds: what it is, its threshold, in how many seeds it is
    met, the rates' spread and the pooled hits."""

    test: str
    source: str
    threshold: float
    what: str
    group: str = "run"
    seeds_meeting: int
    pooled: Pooled


@dataclass(frozen=True, kw_only=True)
class SeedState(Record):
    """A seed of the sweep: done, failed (with its error) or missing; for a finished run of an
    experiment with targets, whether it meets every one and the targets it missed (the
    generalization targets apart); the stages it took from another run (``--reuse``)."""

    state: str
    error: str | None = None
    meets_all: bool | None = None
    missed: list[str] | None = None
    meets_generalization: bool | None = None
    missed_generalization: list[str] | None = None
    taken: list[str] | None = None


@dataclass(frozen=True, kw_only=True)
class ClaimOverRuns(Record):
    """A claim of the claims table over the finished runs: in how many it holds, of how many
    judged it (runs recorded before a claim could be left unjudged counted all as judged)."""

    claim: str
    runs: int
    hold: int
    judged: int | None = None
    criterion: str = ""

    @property
    def judged_runs(self) -> int:
        """The runs that judged it."""
        return self.runs if self.judged is None else self.judged


@dataclass(frozen=True, kw_only=True)
class SweepSummary(Record):
    """``sweep.json``'s ``summary`` (:func:`~mbn.experiments.sweep.summary.summarize`)."""

    seeds: list[int]
    finished: int
    failed: list[int]
    meet_every_target: int
    meet_every_generalization_target: int | None = None
    per_seed: dict[str, SeedState]
    tests: dict[str, TestOverSeeds]
    targets: dict[str, TargetOverSeeds]
    claims: list[ClaimOverRuns]
    analysis: dict[str, Any] | None = None

    @staticmethod
    def numbers(rates: list[float | None]) -> list[float]:
        """Rates as numbers, NaN where the file holds null (no trials)."""
        return [math.nan if r is None else r for r in rates]

    @property
    def judged(self) -> bool:
        """Whether the experiment judges each run by targets (the reproduction, the new
        behaviours) rather than only measuring the runs."""
        return bool(self.targets)


@dataclass(frozen=True, kw_only=True)
class RunEntry(Record):
    """A seed's entry of ``sweep.json``'s ``runs``: its state, its one-line error and its
    seconds (the report reads no more of it)."""

    state: str
    error: str | None = None
    seconds: float | None = None


@dataclass(frozen=True, kw_only=True)
class SweepSettingsRecord(Record):
    """``sweep.json``'s ``settings`` as :meth:`~mbn.experiments.sweep.run.SweepSettings.to_dict`
    writes them, read back without building the config: the experiment (None: the
    reproduction), the seeds, whether quick, and the recorded config (checked apart, by the
    experiment's ``config_from_dict``)."""

    experiment: str | None = None
    seeds: list[int]
    quick: bool
    config: dict[str, Any] | None = None


@dataclass(frozen=True, kw_only=True)
class Growth(Record):
    """One time a sweep gained seeds (``sweep.json``'s ``grown``): the seeds it held before,
    and when (local time, ISO 8601)."""

    seeds_before: list[int]
    at: str


@dataclass(frozen=True, kw_only=True)
class SweepHead(Record):
    """What ``sweep.json`` holds before it is summarized: its settings, its runs, its wall
    seconds, and each time it gained seeds."""

    settings: SweepSettingsRecord | None = None
    runs: dict[str, Any]
    seconds: float | None = None
    grown: list[Growth] = field(default_factory=list)
    #: the installments a combined sweep was made of (``mbn sweep --combine``)
    combined: list[dict[str, Any]] = field(default_factory=list)

    def run(self, seed: int) -> RunEntry:
        """A seed's entry (``missing`` where the sweep has none)."""
        found = self.runs.get(str(seed))
        return RunEntry(state="missing") if found is None else RunEntry.pick(found)


@dataclass(frozen=True, kw_only=True)
class SweepFile(SweepHead):
    """What the report reads of a summarized ``sweep.json``: its head and its summary."""

    summary: SweepSummary


@dataclass(frozen=True, kw_only=True)
class ReuseEntry(Record):
    """One run a run took stages from (``run.json``'s ``reused``, written by
    :func:`~mbn.experiments.pipeline.reuse.take_stages`): where from, the stages taken, the
    code that made them and whether that was other code than the run's."""

    source: str = keyed("from")
    stages: list[str]
    code: dict[str, Any] | None = None
    other_code: bool = False


@dataclass(frozen=True, kw_only=True)
class ReusedStages(Record):
    """What the sweep reads of a seed's ``run.json``: the runs it took stages from
    (``--reuse``; None: none). Read with :meth:`~Record.pick`."""

    reused: list[ReuseEntry] | None = None
