"""``mbn sweep --experiment noise``: the noise levels over runs.

Each run's ``results.json`` records its trials as tests (:func:`noise_tests`): per controller
``N`` (``rf``, ``im_rf``, ``im_lf``, ``mbn``), ``N_none_X`` without noise, ``N_realistic_X``
under the realistic noise, and ``N_CHANNEL_I_X`` at level ``I`` (1, 2, ...) of each channel,
for ``X`` in ``jitter`` and ``heldout``. Over the runs, per channel, level and controller: the
runs' success rates (median, quartiles, min, max) and the pooled trials with a Wilson 95 %
interval; one figure per channel (the medians, the interquartile range as a band).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mbn.experiments.trials import as_test_record
from mbn.stats import describe, wilson_interval

if TYPE_CHECKING:
    from mbn.experiments.pipeline.document import Section

__all__ = ["CONTROLLER_NAMES", "noise_over_runs", "noise_tests", "statistics"]

#: The controllers of ``noise_levels`` (``levels.CONTROLLERS``), named here so that a sweep's
#: report imports no experiment.
CONTROLLER_NAMES = ("rf", "im_rf", "im_lf", "mbn")
_TESTS = ("jitter", "heldout")


def noise_tests(data: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """The ``noise_levels`` stage's trials (its ``curves`` and ``realistic``) as tests:
    ``{name: {"trials", "successes", "success_rate"}}`` (names in the module's docstring)."""
    tests: dict[str, dict[str, Any]] = {}
    for name, channels in data["curves"].items():
        for channel, points in channels.items():
            for i, point in enumerate(points):
                stem = f"{name}_none" if i == 0 else f"{name}_{channel}_{i}"
                for x in _TESTS:
                    tests[f"{stem}_{x}"] = as_test_record(point[x])
    for name, point in data["realistic"].items():
        if name in CONTROLLER_NAMES:
            for x in _TESTS:
                tests[f"{name}_realistic_{x}"] = as_test_record(point[x])
    return tests


def _over(values: list[tuple[float, int, int]]) -> dict[str, Any]:
    """``(rate, successes, trials)`` of the runs -> their spread and the pooled interval."""
    rates = [v[0] for v in values]
    k, n = sum(v[1] for v in values), sum(v[2] for v in values)
    return {
        "rates": rates,
        **describe(rates),
        "pooled": {"successes": k, "trials": n, "wilson95": list(wilson_interval(k, n))},
    }


def statistics(runs: Mapping[int, Mapping[str, Any]]) -> dict[str, Any]:
    """Per channel and controller, the points ``{"level", "jitter", "heldout"}`` over the runs
    that recorded them (the levels are the first such run's: a sweep's runs share settings)."""
    recorded = [r for r in runs.values() if r.get("tests") and r.get("levels")]
    if not recorded:
        return {"runs": 0, "channels": {}}
    first = recorded[0]
    channels: dict[str, Any] = {}
    for channel in first.get("channels", list(first["levels"])):
        levels = first["levels"][channel]
        per: dict[str, list[dict[str, Any]]] = {}
        for name in CONTROLLER_NAMES:
            points = []
            for i, level in enumerate(levels):
                stem = f"{name}_none" if i == 0 else f"{name}_{channel}_{i}"
                point: dict[str, Any] = {"level": float(level)}
                for x in _TESTS:
                    got = [r["tests"].get(f"{stem}_{x}") for r in recorded]
                    got = [g for g in got if g is not None]
                    if not got:
                        break
                    point[x] = _over(
                        [(g["success_rate"], g["successes"], g["trials"]) for g in got]
                    )
                else:
                    points.append(point)
            if len(points) > 1:  # the controller reads the channel
                per[name] = points
        if per:
            channels[channel] = per
    return {"runs": len(recorded), "channels": channels}


def _pct(v: float) -> str:
    return f"{100 * v:.1f}"


def noise_over_runs(
    out: Path, runs: Mapping[int, Mapping[str, Any]]
) -> tuple[dict[str, Any], list[Section], list[tuple[str, str]]]:
    """The statistics (for ``sweep.json``), a report section per channel (the jittered test:
    median [IQR] over runs, and the pooled Wilson interval, per level and controller) and one
    figure per channel (``out/figures/noise_CHANNEL.png``)."""
    from mbn.experiments.noise.report import UNITS, levels_text
    from mbn.experiments.pipeline.document import Section
    from mbn.viz.noise import LABELS, success_vs_noise_over_runs

    stats = statistics(runs)
    sections: list[Section] = []
    images: list[tuple[str, str]] = []
    n = stats["runs"]
    realistic = sorted(
        {levels_text(r["realistic"]["noise"]) for r in runs.values() if r.get("realistic")}
    )
    if realistic:
        sections.append(
            Section(
                "The realistic noise",
                [
                    "The realistic noise of these runs (every channel at once), as they recorded "
                    "it: " + "; ".join(realistic) + "."
                ],
            )
        )
    for channel, per in stats["channels"].items():
        names = list(per)
        levels = max((len(p) for p in per.values()), default=0)
        rows = []
        for i in range(levels):
            row = []
            for name in names:
                pts = per[name]
                if i >= len(pts):
                    row.append("–")
                    continue
                j = pts[i]["jitter"]
                lo, hi = j["pooled"]["wilson95"]
                row.append(
                    f"{_pct(j['median'])} [{_pct(j['q1'])}, {_pct(j['q3'])}] "
                    f"(pooled {_pct(lo)}–{_pct(hi)})"
                )
            level = next(p[i]["level"] for p in per.values() if i < len(p))
            rows.append([f"{level:g}", *row])
        sections.append(
            Section(
                f"Noise over runs: {channel}",
                [
                    f"The jittered test's success (%) over {n} runs at each level of {channel} "
                    "alone: median [interquartile range] of the runs' rates, and the Wilson 95 % "
                    "interval of the pooled trials. The figure adds the held-out maze."
                ],
                table=(["level", *(LABELS.get(x, x) for x in names)], rows),
            )
        )
        file = f"figures/noise_{channel}.png"
        (out / "figures").mkdir(exist_ok=True)
        success_vs_noise_over_runs(channel, per, n, out / file, UNITS.get(channel, ""))
        images.append((file, f"Success against {channel} over {n} runs"))
    return stats, sections, images
