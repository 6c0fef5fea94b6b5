"""The tests of ``mbn reproduce``: which controllers are tested by which rule, and how each test
is made (the paper's protocol, jittered starts, the held-out maze) as :class:`TrialSpec` objects,
from which the ``protocol`` block of ``results.json`` is built."""

from __future__ import annotations

from dataclasses import dataclass

from mbn.experiments.pipeline.results import Record
from mbn.experiments.trials import MAX_STALL_FRACTION, TrialSpec

__all__ = [
    "AGREEMENT_TARGET",
    "ROBUST_TARGET",
    "SUFFIXES",
    "TESTED",
    "TEST_NAMES",
    "WHO",
    "Protocol",
    "protocol_block",
    "test_specs",
]

#: Success rate required from jittered starts and on the held-out maze.
ROBUST_TARGET = 0.95
#: Share of jittered trials in which the interpreter takes the same branches as its network.
AGREEMENT_TARGET = 0.98

#: Controllers tested and the rule each is judged by.
TESTED: tuple[tuple[str, str], ...] = (
    ("rf", "right"),
    ("lf", "left"),
    ("im_rf", "right"),
    ("im_lf", "left"),
    ("mbn", "tiles"),
    ("published_rf", "right"),
    ("published_lf", "left"),
)
#: The three tests of each controller: the paper's protocol, jittered starts, the held-out maze.
SUFFIXES: tuple[str, ...] = ("", "_jitter", "_heldout")
TEST_NAMES: tuple[str, ...] = tuple(f"{name}{suffix}" for name, _ in TESTED for suffix in SUFFIXES)
#: How the report and the claims name each controller.
WHO = {
    "rf": "RF",
    "lf": "LF",
    "im_rf": "IM with the RF program",
    "im_lf": "IM with the LF program",
    "mbn": "MBN (PM + IM)",
    "published_rf": "published W_RF, WE_RF",
    "published_lf": "published W_LF, WE_LF",
}


def test_specs(
    behavior: str,
    *,
    seconds: float,
    jitter_per_mark: int,
    heldout_repeats: int,
    test_seed: int,
    heldout_seed: int,
    initial: str | None = None,
) -> dict[str, TrialSpec]:
    """The three tests of a controller judged by ``behavior`` (suffix -> spec). The MBN
    ("tiles") is judged before its first tile by ``initial``, the rule its file starts with;
    without one (None: a file without ``initial``, at rest) its junctions count from its first
    tile. The others are judged by their rule."""
    if behavior != "tiles":
        initial = "right"
    elif initial is None:
        initial = "none"
    return {
        "": TrialSpec(behavior=behavior, initial=initial, seconds=seconds),
        "_jitter": TrialSpec(
            behavior=behavior,
            initial=initial,
            repeats=jitter_per_mark,
            seconds=seconds,
            exact_first=False,
            seed=test_seed,
        ),
        "_heldout": TrialSpec(
            behavior=behavior,
            initial=initial,
            repeats=heldout_repeats,
            seconds=seconds,
            seed=heldout_seed,
        ),
    }


def _trials(spec: TrialSpec) -> str:
    if spec.exact_first:
        return f"each start mark, then {spec.repeats - 1} jittered"
    return f"{spec.repeats} per start mark, all jittered"


@dataclass(frozen=True, kw_only=True)
class Protocol(Record):
    """How the tests judged their trials (``results.json``'s ``stages.tests.protocol``): the
    junctions judged, the stall limit, the trial's and the MBN's seconds, the MBN's rule before
    its first tile (``"none"`` in runs recorded before it started in a state), the jitter
    (lateral m, along m, heading deg) and the trials of the jittered and held-out tests."""

    junctions: int
    max_stall_fraction: float
    seconds: float
    mbn_seconds: float
    mbn_initial: str = "none"
    jitter: list[float]
    jitter_trials: str
    heldout_trials: str


def protocol_block(plain: dict[str, TrialSpec], mbn: dict[str, TrialSpec]) -> Protocol:
    """The ``protocol`` of ``results.json`` from the specs that ran (a plain network's and the
    MBN's)."""
    return Protocol(
        junctions=plain[""].junctions,
        max_stall_fraction=MAX_STALL_FRACTION,
        seconds=plain[""].seconds,
        mbn_seconds=mbn[""].seconds,
        mbn_initial=mbn[""].initial,
        jitter=list(plain["_jitter"].jitter),
        jitter_trials=_trials(plain["_jitter"]),
        heldout_trials=_trials(plain["_heldout"]),
    )
