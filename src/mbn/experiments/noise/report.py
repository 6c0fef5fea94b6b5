"""The claims and the report of ``mbn run noise``."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from mbn.experiments.pipeline import RunDir
from mbn.experiments.pipeline.document import Section, claims_section, write_document
from mbn.experiments.pipeline.results import RunResults
from mbn.experiments.stages.noise_levels import (
    CONTROLLERS,
    LevelPoint,
    NoiseLevelsResult,
    NoiseLevelsStage,
)
from mbn.io import read_json
from mbn.viz.noise import LABELS

__all__ = ["TITLE", "claims", "levels_text", "write_report"]

TITLE = "mbn: what survives noise"

#: The units of the channels' levels, for the figures.
UNITS = {
    "sonar_std": "m",
    "wheel_std": "relative",
    "neuron_std": "potential",
    "corridor_scale": "relative",
    "sonar_cone": "degrees",
    "wheel_bias": "relative",
}


def levels_text(levels: Mapping[str, float]) -> str:
    """Noise levels as a run recorded them, the channels that are on: ``sonar_std = 0.02,
    wheel_std = 0.05``."""
    return ", ".join(f"{k} = {v:g}" for k, v in levels.items() if v > 0) or "every channel off"


def _falls_below(points: list[LevelPoint], threshold: float) -> str:
    """The first level where the jittered success rate is below ``threshold``, or that it stays
    above."""
    for p in points:
        if p.jitter.rate < threshold:
            return f"{p.level:g}"
    return f"> {points[-1].level:g}"


def evolved_under(data: NoiseLevelsResult) -> str:
    """The noise the controllers were evolved under, in words (runs recorded before it was
    recorded were evolved without)."""
    levels = data.evolved_under
    if not levels:
        return "without noise"
    return "under noise (" + ", ".join(f"{k} = {v:g}" for k, v in levels.items()) + ")"


def claims(stages: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """The paper's doubt about noise, and where each controller breaks."""
    data = NoiseLevelsStage.from_json(stages[NoiseLevelsStage.name])
    mbn = data.realistic_point("mbn")
    evolved = evolved_under(data)
    rows = [
        {
            "claim": "noise introduced by actuators and sensors should be compensated: this "
            "could be not the case for a real environment (paper, section 4)",
            "measured": f"the MBN evolved {evolved} passes {mbn.jitter.rate:.1%} of "
            f"the jittered trials and {mbn.heldout.rate:.1%} held out under the "
            f"realistic noise ({levels_text(data.realistic_noise)}); "
            + ", ".join(
                f"{LABELS[n]} {data.realistic_point(n).jitter.rate:.1%}"
                for n in CONTROLLERS
                if n != "mbn"
            ),
            "target": "the MBN keeps >= 95 % of jittered trials (the level asked of an MBN "
            "evolved under this noise"
            + ("; this one was evolved without)" if evolved == "without noise" else ")"),
            "pass": mbn.jitter.rate >= 0.95,
        }
    ]
    curves = data.curves
    for channel in data.channels:
        if channel not in curves.get("mbn", {}):
            continue
        rows.append(
            {
                "claim": f"where {channel} breaks the controllers (below 50 % of jittered trials)",
                "measured": "; ".join(
                    f"{LABELS[n]} at {_falls_below(curves[n][channel], 0.5)}"
                    for n in CONTROLLERS
                    if channel in curves[n]
                ),
                "target": "measured",
                "pass": None,
            }
        )
    return rows


def write_report(rundir: RunDir) -> None:
    """``report.md``, ``report.html`` and one figure per channel."""
    from mbn.viz.noise import success_vs_noise

    run = RunResults.pick(read_json(rundir.results), str(rundir.results))
    stages = {name: rundir.read_stage(name) for name in run.stages}
    data = NoiseLevelsStage.from_json(stages[NoiseLevelsStage.name])
    rows = claims(stages)
    images = []
    for channel in data.channels:
        curves = {
            n: [p.to_json() for p in c[channel]] for n, c in data.curves.items() if channel in c
        }
        file = f"figures/noise_{channel}.png"
        success_vs_noise(channel, curves, rundir.root / file, UNITS.get(channel, ""))
        images.append((file, f"Success against {channel}"))
    evolved = evolved_under(data)
    realistic = {n: data.realistic_point(n) for n in CONTROLLERS}
    secs = [
        Section(
            "What this run did",
            [
                f"Seed {run.seed}. The reproduction's RF, interpreter and MBN, evolved "
                f"{evolved}, tested on the jittered test maze and the held-out one with each "
                "channel of the noise model alone at increasing levels, and with every channel "
                "at once at a realistic level (docs/noise.md). "
                f"{data.trials.jitter_per_mark} jittered trials per start mark, "
                f"{data.trials.heldout_repeats} per held-out mark; intervals: Wilson 95 %.",
            ],
        ),
        claims_section(rows),
        Section(
            "Realistic noise",
            [levels_text(data.realistic_noise)],
            table=(
                ["controller", "jittered", "95 % CI", "held-out", "95 % CI"],
                [
                    [
                        LABELS[n],
                        f"{p.jitter.successes}/{p.jitter.trials}",
                        "{:.1%}–{:.1%}".format(*p.jitter.wilson95),
                        f"{p.heldout.successes}/{p.heldout.trials}",
                        "{:.1%}–{:.1%}".format(*p.heldout.wilson95),
                    ]
                    for n, p in realistic.items()
                ],
            ),
        ),
        Section("Success against each channel", images=images),
    ]
    write_document(rundir.root, "report", TITLE, secs)
