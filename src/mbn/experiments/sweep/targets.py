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

The thresholds are those of the claims table (:data:`~mbn.experiments.reproduce.claims.
ROBUST_TARGET`, :data:`~mbn.experiments.reproduce.claims.AGREEMENT_TARGET`), compared exactly
(as fractions: 190/200 meets 95 %).
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from mbn.experiments.reproduce.claims import AGREEMENT_TARGET, ROBUST_TARGET
from mbn.experiments.reproduce.protocol import WHO

__all__ = ["TARGETS", "Target", "measure", "meets"]


@dataclass(frozen=True)
class Target:
    """One per-run target.

    Attributes:
        name: the test's name (``rf_jitter``) or, for agreement, ``agreement_<test>``.
        source: ``"tests"`` (``results["tests"][test]``: successes / trials) or ``"agreement"``
            (``results["stages"]["tests"]["agreement"][test]``: same_branches / trials).
        test: the key in that table.
        threshold: the least rate that meets it (a fraction; 1 means every trial).
        what: how the report describes it.
    """

    name: str
    source: str
    test: str
    threshold: Fraction
    what: str

    @property
    def label(self) -> str:
        """The threshold as the report writes it (``10/10``-style "all", or ``>= 95 %``)."""
        return "all trials" if self.threshold == 1 else f">= {float(self.threshold):.0%}"


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


def measure(target: Target, results: dict[str, Any]) -> tuple[int, int]:
    """``(hits, trials)`` of ``target`` in one run's ``results.json``."""
    if target.source == "tests":
        t = results["tests"][target.test]
        return int(t["successes"]), int(t["trials"])
    a = results["stages"]["tests"]["agreement"][target.test]
    return int(a["same_branches"]), int(a["trials"])


def meets(target: Target, hits: int, trials: int) -> bool:
    """Whether ``hits`` of ``trials`` meet ``target`` (no trials: not met)."""
    return trials > 0 and Fraction(hits, trials) >= target.threshold
