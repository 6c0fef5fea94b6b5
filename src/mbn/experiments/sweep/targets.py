"""The per-run targets of a sweep: what each seed's run must reach to "meet every target".

One table, :data:`TARGETS`, read by the summary, the report and the docs (``docs/sweep.md``):

============================  ==========================================  ===========
what                          where in ``results.json``                   target
============================  ==========================================  ===========
paper protocol (10 marks)     ``tests.{rf,lf,im_rf,im_lf,mbn}``           10/10
200 jittered starts           ``tests.{rf,...,mbn}_jitter``               >= 95 %
held-out maze                 ``tests.{rf,...,mbn}_heldout``              >= 95 %
interpreter agreement         ``stages.tests.agreement.im_{rf,lf}_jitter`` >= 98 %
============================  ==========================================  ===========

The thresholds are those of the claims table (:data:`~mbn.experiments.stages.protocol.
ROBUST_TARGET`, :data:`~mbn.experiments.stages.protocol.AGREEMENT_TARGET`), compared exactly
(as fractions: 190/200 meets 95 %).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from mbn.experiments.stages.protocol import AGREEMENT_TARGET, ROBUST_TARGET, WHO
from mbn.experiments.stages.records import Agreement, Tally

__all__ = [
    "GENERALIZATION_TARGETS",
    "TARGETS",
    "ZERO_SHOT_TARGET",
    "Target",
    "generalization_targets",
    "measure",
    "meets",
]

#: The zero-shot suite's target: pooled success over its mazes.
ZERO_SHOT_TARGET = 0.90


@dataclass(frozen=True)
class Target:
    """One per-run target.

    Attributes:
        name: the test's name (``rf_jitter``) or, for agreement, ``agreement_<test>``.
        source: ``"tests"`` (``results["tests"][test]``: successes / trials) or ``"agreement"``
            (same_branches / trials of an agreement record, by default
            ``results["stages"]["tests"]["agreement"][test]``).
        test: the key in that table.
        threshold: the least rate that meets it (a fraction; 1 means every trial).
        what: how the report describes it.
        where: the keys from ``results.json`` to the record's table, when not the default of
            its source (another experiment's agreement records, e.g. ``("stages", "im_full",
            "agreement")``).
    """

    name: str
    source: str
    test: str
    threshold: Fraction
    what: str
    where: tuple[str, ...] = ()

    @property
    def path(self) -> tuple[str, ...]:
        """The keys from ``results.json`` to the record."""
        if self.source in SPLIT_SOURCES:
            return self.where
        default = ("tests",) if self.source == "tests" else ("stages", "tests", "agreement")
        return (*(self.where or default), self.test)

    @property
    def label(self) -> str:
        """The threshold as the report writes it (``10/10``-style "all", or ``>= 95 %``)."""
        return "all trials" if self.threshold == 1 else f">= {float(self.threshold):.0%}"


#: Sources of a generalization target: a split record of a ``generalization`` stage
#: (:func:`mbn.experiments.generalization.split_record`), its pooled trials or its mazes each
#: at 95 %.
SPLIT_SOURCES = ("split_pooled", "split_mazes")


def _fraction(rate: float) -> Fraction:
    return Fraction(rate).limit_denominator(1000)


_FOLLOWERS = ("rf", "lf", "im_rf", "im_lf", "mbn")

#: Every per-run target, in the order the report lists them.
TARGETS: tuple[Target, ...] = (
    *(Target(n, "tests", n, Fraction(1), f"{WHO[n]}: paper protocol") for n in _FOLLOWERS),
    *(
        Target(
            f"{n}_jitter",
            "tests",
            f"{n}_jitter",
            _fraction(ROBUST_TARGET),
            f"{WHO[n]}: jittered starts",
        )
        for n in _FOLLOWERS
    ),
    *(
        Target(
            f"{n}_heldout",
            "tests",
            f"{n}_heldout",
            _fraction(ROBUST_TARGET),
            f"{WHO[n]}: held-out maze",
        )
        for n in _FOLLOWERS
    ),
    Target(
        "agreement_im_rf_jitter",
        "agreement",
        "im_rf_jitter",
        _fraction(AGREEMENT_TARGET),
        "IM with RF's program takes RF's exits (jittered starts)",
    ),
    Target(
        "agreement_im_lf_jitter",
        "agreement",
        "im_lf_jitter",
        _fraction(AGREEMENT_TARGET),
        "IM with LF's program takes LF's exits (jittered starts)",
    ),
)


def _record_at(results: Mapping[str, Any], path: tuple[str, ...]) -> Any:
    """The JSON object at ``path`` in a ``results.json`` (None where the run did not record
    it): where a target's record lies, as :attr:`Target.path` declares it."""
    record: Any = results
    for key in path:
        if not isinstance(record, Mapping) or key not in record:
            return None
        record = record[key]
    return record


def measure(target: Target, results: Mapping[str, Any]) -> tuple[int, int]:
    """``(hits, trials)`` of ``target`` in one run's ``results.json`` (successes of a test,
    same branches of an agreement, a split's pooled successes or its mazes at 95 %; ``(0, 0)``
    where the run has no such record). The record is read typed (:class:`Tally`,
    :class:`Agreement`, :class:`SplitRecord`); a record of the wrong shape is refused in one
    line naming the target."""
    from mbn.experiments.generalization import SplitRecord

    found = _record_at(results, target.path)
    if found is None:
        return 0, 0  # the run did not record it: no trials, not met
    where = f"target {target.name}"
    if target.source in SPLIT_SOURCES:
        split = SplitRecord.pick(found, where)
        if target.source == "split_pooled":
            return split.pooled.successes, split.pooled.trials
        return split.mazes_at_95, len(split.mazes)
    if target.source == "tests":
        test = Tally.pick(found, where)
        return test.successes, test.trials
    agreement = Agreement.pick(found, where)
    return agreement.same_branches, agreement.trials


def generalization_targets(
    controllers: tuple[tuple[str, str], ...], stage: str = "generalization"
) -> tuple[Target, ...]:
    """The generalization targets of a ``generalization`` stage's controllers (``(name, what
    the report calls it)``): on the test split pooled success >= 95 % and >= 90 % of the mazes
    each at >= 95 %, and on the zero-shot suite pooled >= 90 % (``docs/generalization.md``)."""
    from mbn.experiments.generalization import MAZE_SHARE_TARGET, POOLED_TARGET

    out: list[Target] = []
    for name, what in controllers:
        base = ("stages", stage, "controllers", name, "splits")
        out += [
            Target(
                f"{name}_test",
                "split_pooled",
                f"{name}/test",
                _fraction(POOLED_TARGET),
                f"{what}: test split, pooled",
                (*base, "test"),
            ),
            Target(
                f"{name}_test_mazes",
                "split_mazes",
                f"{name}/test",
                _fraction(MAZE_SHARE_TARGET),
                f"{what}: test split, mazes at >= 95 %",
                (*base, "test"),
            ),
            Target(
                f"{name}_zero_shot",
                "split_pooled",
                f"{name}/zero-shot",
                _fraction(ZERO_SHOT_TARGET),
                f"{what}: zero-shot suite, pooled",
                (*base, "zero-shot"),
            ),
        ]
    return tuple(out)


def meets(target: Target, hits: int, trials: int) -> bool:
    """Whether ``hits`` of ``trials`` meet ``target`` (no trials: not met)."""
    return trials > 0 and Fraction(hits, trials) >= target.threshold


#: The reproduction's generalization targets (its ``generalization`` stage).
GENERALIZATION_TARGETS = generalization_targets(tuple((n, WHO[n]) for n in _FOLLOWERS))
