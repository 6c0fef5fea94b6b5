"""``mbn sweep`` of the switch: no per-run target; each pair's sweep over the runs (the spec's
``analysis``: :func:`~mbn.experiments.switch.over_runs.switch_over_runs`)."""

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

__all__ = ["SWITCH_SPEC"]


def _analysis(
    out: Path, runs: Mapping[int, Mapping[str, Any]]
) -> tuple[dict[str, Any], list[Section], list[tuple[str, str]]]:
    from mbn.experiments.switch.over_runs import switch_over_runs

    return switch_over_runs(out, runs)


SWITCH_SPEC = SweepSpec(
    name="switch",
    title="mbn sweep: the switch between programs, over seeds",
    command="mbn run switch",
    targets=(),
    tests=(),
    groups=(),
    targets_text="No run has a per-run target here: each run's claims (docs/switch.md) are "
    "counted over the runs below, with the seeds that miss them.",
    de_stages=CONTROLLER_DE_STAGES,
    curve=controller_curve,
    load=loader("switch"),
    analysis=_analysis,
)
