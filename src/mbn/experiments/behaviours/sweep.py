"""``mbn sweep`` of new-behaviours: the per-run targets of each section (the fully programmable
interpreter, the new rules by programs alone, the three-behaviour MBN), the tests its report
tabulates and the DE curves it draws."""

from __future__ import annotations

from fractions import Fraction

from mbn.experiments.stages.protocol import SUFFIXES
from mbn.experiments.sweep.specs import SweepSpec, by_trials, loader, stage_history
from mbn.experiments.sweep.targets import Target, generalization_targets

__all__ = ["NEW_BEHAVIOURS_SPEC", "NEW_BEHAVIOURS_TARGETS"]


def _nb_tests(stem: str, what: str) -> tuple[Target, ...]:
    return (
        Target(stem, "tests", stem, Fraction(1), f"{what}: start marks"),
        Target(f"{stem}_jitter", "tests", f"{stem}_jitter", Fraction(95, 100), f"{what}: jittered"),
        Target(
            f"{stem}_heldout", "tests", f"{stem}_heldout", Fraction(95, 100), f"{what}: held-out"
        ),
    )


def _nb_agreement(test: str, where: tuple[str, ...], what: str) -> Target:
    return Target(f"agreement_{test}", "agreement", test, Fraction(98, 100), what, where)


_IM_FULL = ("stages", "im_full", "agreement")
_TESTS3 = ("stages", "tests3", "agreement")

#: The per-run targets of ``new-behaviours`` (issue 19, sections 2 to 4): the fully programmable
#: interpreter with RF's and LF's programs, each new rule by a program alone and its decoded
#: network's agreement with it, and the three-behaviour MBN on three-colour and on two-colour
#: tiles (the two behaviours still there after the third was added).
NEW_BEHAVIOURS_TARGETS: tuple[Target, ...] = (
    *_nb_tests("im_full_rf", "fully programmable IM, RF's program"),
    *_nb_tests("im_full_lf", "fully programmable IM, LF's program"),
    _nb_agreement("im_full_rf_jitter", _IM_FULL, "fully programmable IM takes RF's exits"),
    _nb_agreement("im_full_lf_jitter", _IM_FULL, "fully programmable IM takes LF's exits"),
    *_nb_tests("im_full_straight_right", "straight-right by a program alone"),
    _nb_agreement(
        "im_full_straight_right_jitter", _TESTS3, "the decoded network takes the program's exits"
    ),
    *_nb_tests("im_full_straight_left", "straight-left by a program alone"),
    _nb_agreement(
        "im_full_straight_left_jitter", _TESTS3, "the decoded network takes the program's exits"
    ),
    *_nb_tests("mbn3", "three-behaviour MBN"),
    *_nb_tests("mbn3_two_tiles", "three-behaviour MBN on the two-behaviour test"),
)

#: The tests of a new-behaviours run, from its start marks, in the report's order.
_NB_STEMS = (
    "im_full_rf",
    "im_full_lf",
    "im_full_straight_right",
    "net_straight_right",
    "im_full_straight_left",
    "net_straight_left",
    "mbn3",
    "mbn3_two_tiles",
)
_NB_TESTS = tuple(f"{stem}{suffix}" for stem in _NB_STEMS for suffix in SUFFIXES)

NEW_BEHAVIOURS_SPEC = SweepSpec(
    name="new-behaviours",
    title="mbn sweep: new behaviours by programs alone, over seeds",
    command="mbn run new-behaviours",
    targets=NEW_BEHAVIOURS_TARGETS,
    generalization=generalization_targets(
        (
            ("straight_right", "straight-right by a program alone"),
            ("straight_left", "straight-left by a program alone"),
            ("mbn3", "three-behaviour MBN"),
        )
    ),
    tests=_NB_TESTS,
    groups=by_trials("Start marks", _NB_STEMS),
    targets_text="The targets (`mbn.experiments.sweep.specs`): every start mark, and at least "
    "95 % of the jittered and the held-out trials, for the fully programmable interpreter with "
    "RF's and with LF's program, for each new rule by a program alone, and for the "
    "three-behaviour MBN on the three-tile maze and on the two-behaviour test; the interpreter "
    "takes RF's and LF's exits, and each new rule's decoded network the program's, in at least "
    "98 % of the jittered trials. The decoded networks (`net_*`) have no target of their own.",
    de_stages={
        "rf": "RF (12 genes)",
        "lf": "LF (3 genes)",
        "mbn3": "PM of the three-behaviour MBN",
    },
    curve=stage_history,
    load=loader("new-behaviours"),
)
