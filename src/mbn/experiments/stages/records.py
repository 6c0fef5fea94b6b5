"""The pieces several stages' results share (:class:`~mbn.experiments.pipeline.results.Record`
types): a DE run's history, a success on the validation mazes, the perturbations of robust
fitness, a restart of an evolution, judged trials and two controllers' agreement."""

from __future__ import annotations

from dataclasses import dataclass

from mbn.experiments.pipeline.results import Record, optional

__all__ = [
    "Agreement",
    "AgreementCheck",
    "History",
    "Perturbation",
    "RateRecord",
    "Restart",
    "Tally",
    "TestMazes",
    "TrialCounts",
    "TrialSummary",
    "Validation",
]


@dataclass(frozen=True, kw_only=True)
class History(Record):
    """Best and mean finite fitness of every generation (generation 0 first)."""

    best: list[float]
    mean: list[float]


@dataclass(frozen=True, kw_only=True)
class Validation(Record):
    """A candidate's success on the validation mazes (:func:`~mbn.experiments.stages.common.
    validate`); on maze episodes also how many of the mazes reach the target each."""

    trials: int
    successes: int
    success_rate: float
    meets_target: bool
    mazes: int | None = optional()
    mazes_at_target: int | None = optional()


@dataclass(frozen=True, kw_only=True)
class Perturbation(Record):
    """Robust fitness: a genome scored with ``copies`` perturbed copies (Gaussian ``sigma``)."""

    copies: int
    sigma: float


@dataclass(frozen=True, kw_only=True)
class Restart(Record):
    """One independent DE run of a stage that evolves several and keeps one."""

    best_fitness: float
    history: History
    best_genome: list[float]
    validation: Validation | None = optional()


@dataclass(frozen=True, kw_only=True)
class RateRecord(Record):
    """Successes of trials with the rate and its Wilson 95 % interval (how the noise levels and
    the ablations record a test: :func:`~mbn.experiments.trials.rate_record`)."""

    successes: int
    trials: int
    rate: float
    wilson95: list[float]


@dataclass(frozen=True, kw_only=True)
class TrialCounts(Record):
    """The trials per test of the noise levels and the ablations: jittered trials per start
    mark, repeats per held-out mark."""

    jitter_per_mark: int
    heldout_repeats: int


@dataclass(frozen=True, kw_only=True)
class TestMazes(Record):
    """A test stage's mazes: the paper protocol's (or the stage's own) and the held-out one,
    by name."""

    test: str
    heldout: str


@dataclass(frozen=True, kw_only=True)
class Tally(Record):
    """What every test record of every experiment has (a :class:`TrialSummary`, a noise
    level's or an ablation's test): its trials, successes and success rate; read with
    :meth:`~mbn.experiments.pipeline.results.Record.pick`."""

    trials: int
    successes: int
    success_rate: float


@dataclass(frozen=True, kw_only=True)
class TrialSummary(Record):
    """Judged trials (:func:`mbn.experiments.trials.summary`): trials, successes, success rate,
    trials the time limit ended first (neither successes nor failures), junctions judged and
    taken right, and the mean share of stalled steps."""

    trials: int
    successes: int
    success_rate: float
    timed_out: int
    junctions: int
    correct_junctions: int
    mean_stall_fraction: float


@dataclass(frozen=True, kw_only=True)
class Agreement(Record):
    """Two controllers on the same trials (:func:`mbn.experiments.trials.agreement`): the
    trials where they took the same exit at every judged junction, and the rate."""

    trials: int
    same_branches: int
    rate: float


@dataclass(frozen=True, kw_only=True)
class AgreementCheck(Record):
    """An agreement on the validation mazes (:class:`Agreement`) and whether it meets its
    target."""

    trials: int
    same_branches: int
    rate: float
    meets_target: bool
