"""Success against noise: one figure per channel, one line per controller, Wilson intervals."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from mbn.viz.style import new_figure, save_png

__all__ = ["success_vs_noise", "success_vs_noise_over_runs"]

#: How the figures name the controllers.
LABELS = {
    "rf": "RF",
    "im_rf": "IM, RF's program",
    "im_lf": "IM, LF's program",
    "mbn": "MBN",
}


def _panels(
    channel: str,
    curves: Mapping[str, Sequence[Mapping[str, Any]]],
    draw: Callable[[Any, int, str, Sequence[Mapping[str, Any]], str], None],
    unit: str,
) -> Any:
    """Two panels (jittered test, held-out maze) of success against a channel's levels, drawn
    evenly spaced and labelled (they are chosen roughly geometric), 50 % and 95 % marked;
    ``draw(ax, k, controller, points, test)`` draws controller ``k``'s line."""
    fig = new_figure((10, 4))
    axes = fig.subplots(1, 2, sharey=True)
    panels = (("jitter", "jittered test"), ("heldout", "held-out maze"))
    for ax, (test, what) in zip(axes, panels, strict=True):
        ticks: list[float] = []
        for k, (name, points) in enumerate(curves.items()):
            draw(ax, k, name, points, test)
            if len(points) > len(ticks):
                ticks = [float(p["level"]) for p in points]
        ax.set_xticks(range(len(ticks)), [f"{v:g}" for v in ticks])
        for y, style in ((95, ":"), (50, "--")):
            ax.axhline(y, color="0.5", lw=0.8, ls=style)
        ax.set_xlabel(f"{channel}" + (f" ({unit})" if unit else ""))
        ax.set_title(f"{what}")
        ax.set_ylim(-3, 103)
    axes[1].legend(loc="lower left", fontsize=8)
    return fig, axes


def success_vs_noise(
    channel: str,
    curves: Mapping[str, Sequence[Mapping[str, Any]]],
    path: Path,
    unit: str = "",
) -> None:
    """``curves[controller]``: the points of one channel, each ``{"level", "jitter",
    "heldout"}`` with ``rate`` and ``wilson95``. Two panels (jittered test, held-out maze),
    success against level, the 95 % Wilson interval as error bars, 50 % and 95 % marked."""

    def draw(ax: Any, k: int, name: str, points: Sequence[Mapping[str, Any]], test: str) -> None:
        x = [v + 0.06 * (k - 1.5) for v in range(len(points))]
        rate = [100 * p[test]["rate"] for p in points]
        # the interval's ends less the rate (>= 0 up to rounding)
        lo = [max(0.0, 100 * (p[test]["rate"] - p[test]["wilson95"][0])) for p in points]
        hi = [max(0.0, 100 * (p[test]["wilson95"][1] - p[test]["rate"])) for p in points]
        ax.errorbar(x, rate, yerr=[lo, hi], marker="o", ms=4, capsize=2, lw=1.2,
                    label=LABELS.get(name, name), color=f"C{k}")  # fmt: skip

    fig, axes = _panels(channel, curves, draw, unit)
    axes[0].set_ylabel("trials passed (%)")
    fig.suptitle(f"Success under noise: {channel} (95 % Wilson intervals)")
    save_png(fig, path)


def success_vs_noise_over_runs(
    channel: str,
    curves: Mapping[str, Sequence[Mapping[str, Any]]],
    runs: int,
    path: Path,
    unit: str = "",
) -> None:
    """The same figure over runs: ``curves[controller]`` holds the points of one channel, each
    ``{"level", "jitter", "heldout"}`` with the runs' ``median``, ``q1`` and ``q3`` (rates). One
    line per controller through the medians, its interquartile range as a band."""

    def draw(ax: Any, k: int, name: str, points: Sequence[Mapping[str, Any]], test: str) -> None:
        x = list(range(len(points)))
        q1 = [100 * p[test]["q1"] for p in points]
        q3 = [100 * p[test]["q3"] for p in points]
        ax.fill_between(x, q1, q3, color=f"C{k}", alpha=0.15, lw=0)
        med = [100 * p[test]["median"] for p in points]
        ax.plot(x, med, marker="o", ms=4, lw=1.2, color=f"C{k}", label=LABELS.get(name, name))

    fig, axes = _panels(channel, curves, draw, unit)
    axes[0].set_ylabel("trials passed (%), median over runs")
    fig.suptitle(f"Success under noise over {runs} runs: {channel} (bands: interquartile range)")
    save_png(fig, path)
