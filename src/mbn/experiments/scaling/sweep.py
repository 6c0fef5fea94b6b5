"""``mbn sweep`` of the scaling experiment: no per-run target of its own beyond the run's claims;
the MBNs of K behaviours over the runs (the spec's ``analysis``:
:func:`~mbn.experiments.scaling.over_runs.scaling_over_runs`)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mbn.experiments.sweep.specs import (
    CONTROLLER_DE_STAGES,
    SweepSpec,
    controller_curve,
    loader,
)

if TYPE_CHECKING:
    from mbn.experiments.pipeline.document import Section

__all__ = ["SCALING_SPEC"]


def _analysis(
    out: Path, runs: Mapping[int, Mapping[str, Any]]
) -> tuple[dict[str, Any], list[Section], list[tuple[str, str]]]:
    from mbn.experiments.scaling.over_runs import scaling_over_runs

    return scaling_over_runs(out, runs)


SCALING_SPEC = SweepSpec(
    name="scaling",
    title="mbn sweep: MBNs of 2 to 6 behaviours, over seeds",
    command="mbn run scaling",
    targets=(),
    tests=(),
    groups=(),
    targets_text="The runs' claims (docs/scaling.md) are counted over the runs below: the "
    "test split's targets per K, and forgetting within ±2 points in at least 18 of 20 runs.",
    de_stages=CONTROLLER_DE_STAGES,
    curve=controller_curve,
    load=loader("scaling"),
    analysis=_analysis,
)
