"""``mbn sweep`` of programs-vs-dynamics: no per-run target; the contenders compared over the
runs (the spec's ``analysis``: :func:`~mbn.experiments.contest.over_runs.contest_over_runs`)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mbn.experiments.stages.protocol import SUFFIXES
from mbn.experiments.sweep.specs import SweepSpec, by_trials, loader, stage_history

if TYPE_CHECKING:
    from mbn.experiments.pipeline.document import Section

__all__ = ["CONTEST_SPEC"]


def _contest_analysis(
    out: Path, runs: Mapping[int, Mapping[str, Any]]
) -> tuple[dict[str, Any], list[Section], list[tuple[str, str]]]:
    from mbn.experiments.contest.over_runs import contest_over_runs

    return contest_over_runs(out, runs)


_CONTEST_STEMS = tuple(
    f"{prefix}{who}_{rule}"
    for rule in ("straight_right", "straight_left")
    for prefix, who in (
        ("", "programs"),
        ("im_", "programs"),
        ("", "scratch"),
        ("", "neighbour"),
        ("", "programs_k"),
        ("im_", "programs_k"),
    )
) + tuple(
    f"{who}_three_behaviours"
    for who in ("programs", "monolithic", "grown5", "grown10", "oracle", "gate")
)

CONTEST_SPEC = SweepSpec(
    name="programs-vs-dynamics",
    title="mbn sweep: learning programs against learning dynamics, over seeds",
    command="mbn run programs-vs-dynamics",
    targets=(),
    tests=tuple(f"{stem}{suffix}" for stem in _CONTEST_STEMS for suffix in SUFFIXES),
    groups=by_trials("Start marks (each contender's final best)", _CONTEST_STEMS),
    targets_text="No test has a per-run target: the contenders are compared over runs "
    "(below). `im_programs_*` is program search's final program through the interpreter itself "
    "(`im_programs_k_*`: the interpreter with only k connections programmable); the others are "
    "the networks; `*_three_behaviours`: the three-behaviour task's final "
    "controllers, the MBN (`programs`), the monolithic CTRNN evolved at once and grown rule by "
    "rule (`grown5`, `grown10`: its sizes), and the MBN's baselines built "
    "from its programs (`oracle`: the weights swapped; `gate`: the decoded networks side by "
    "side), judged by the last tile's rule.",
    de_stages={"rf": "RF (12 genes)"},
    curve=stage_history,
    load=loader("programs-vs-dynamics"),
    analysis=_contest_analysis,
)
