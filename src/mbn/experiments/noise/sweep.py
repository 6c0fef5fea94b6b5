"""``mbn sweep`` of the noise levels: no per-run target; each channel level by level over the
runs (the spec's ``analysis``: :func:`~mbn.experiments.noise.over_runs.noise_over_runs`)."""

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

__all__ = ["NOISE_SPEC"]


def _noise_analysis(
    out: Path, runs: Mapping[int, Mapping[str, Any]]
) -> tuple[dict[str, Any], list[Section], list[tuple[str, str]]]:
    from mbn.experiments.noise.over_runs import noise_over_runs

    return noise_over_runs(out, runs)


#: The controllers of ``mbn run noise`` (``noise.over_runs.CONTROLLER_NAMES``).
_NOISE_CONTROLLERS = ("rf", "im_rf", "im_lf", "mbn")

NOISE_SPEC = SweepSpec(
    name="noise",
    title="mbn sweep: the controllers under noise, over seeds",
    command="mbn run noise",
    targets=(),
    tests=tuple(
        f"{n}_{p}_{x}"
        for p in ("none", "realistic")
        for n in _NOISE_CONTROLLERS
        for x in ("jitter", "heldout")
    ),
    groups=tuple(
        (title, tuple(f"{n}_{p}_{x}" for n in _NOISE_CONTROLLERS))
        for p, what in (("none", "No noise"), ("realistic", "Realistic noise"))
        for x, title in (("jitter", f"{what}, jittered"), ("heldout", f"{what}, held out"))
    ),
    targets_text="No run has a per-run target here (`docs/noise.md`): `N_none_*` is controller N "
    "without noise, `N_realistic_*` under the realistic noise (its levels as the runs recorded "
    "them: below); the sections below give each channel level by level over the runs.",
    de_stages=CONTROLLER_DE_STAGES,
    curve=controller_curve,
    load=loader("noise"),
    analysis=_noise_analysis,
)
