"""Pictures of a sweep over seeds (``mbn sweep``), drawn from numbers the seed folders recorded:
nothing here simulates.

* :func:`de_bands` — the DE best fitness per generation of each stage, as a band over the seeds
  (min–max and the interquartile range) with the median run drawn;
* :func:`rate_boxes` — box plots of the per-seed success rates of each test, with its target.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from mbn.viz.style import new_figure, save_png

__all__ = ["de_bands", "median_run", "rate_boxes"]


def median_run(finals: Mapping[int, float]) -> int:
    """The seed whose final best fitness is the median (the lower one of an even count)."""
    ordered = sorted(finals, key=lambda s: (finals[s], s))
    return ordered[(len(ordered) - 1) // 2]


def de_bands(
    curves: Mapping[str, Mapping[int, Sequence[float]]],
    titles: Mapping[str, str],
    path: Path,
) -> None:
    """One panel per stage of ``curves`` (``stage -> seed -> best fitness per generation``):
    min–max and IQR bands over the seeds and the median run's curve."""
    names = [n for n in curves if curves[n]]
    cols = 2 if len(names) > 1 else 1
    rows = max(1, -(-len(names) // cols))
    fig = new_figure((11, 3.6 * rows))
    axes = np.atleast_1d(fig.subplots(rows, cols)).ravel()
    for ax, name in zip(axes, names, strict=False):
        per_seed = curves[name]
        length = min(len(c) for c in per_seed.values())
        a = np.asarray([list(c)[:length] for c in per_seed.values()], dtype=float)
        g = np.arange(length)
        q1, q3 = np.percentile(a, [25, 75], axis=0)
        ax.fill_between(
            g,
            a.min(axis=0),
            a.max(axis=0),
            color="C0",
            alpha=0.15,
            lw=0,
            label="min–max over seeds",
        )
        ax.fill_between(g, q1, q3, color="C0", alpha=0.4, lw=0, label="interquartile range")
        med = median_run({s: float(list(c)[length - 1]) for s, c in per_seed.items()})
        ax.plot(
            g, list(per_seed[med])[:length], color="C3", lw=1.6, label=f"median run (seed {med})"
        )
        k = len(per_seed)
        ax.set_title(f"{titles.get(name, name)}: DE best fitness, {k} seed{'s' * (k != 1)}")
        ax.xaxis.get_major_locator().set_params(integer=True)
        ax.set_xlabel("generation")
        ax.set_ylabel("best fitness")
        ax.legend(loc="best", fontsize=8)
    for ax in axes[len(names) :]:
        ax.set_visible(False)
    save_png(fig, path)


def _short(name: str) -> str:
    """A test's name as a box plot's panel labels it (its title names the trials)."""
    name = name.removeprefix("agree ")
    for suffix in ("_jitter", "_heldout"):
        name = name.removesuffix(suffix)
    return name


def rate_boxes(
    rates: Mapping[str, Sequence[float]],
    targets: Mapping[str, float],
    path: Path,
    groups: Sequence[tuple[str, Sequence[str]]],
) -> None:
    """Box plots of the per-seed rates of each test (seeds as dots), one panel per group
    (``(title, [test names])``; a group without tests has no panel); a red tick marks each
    test's target."""
    groups = [(title, names) for title, names in groups if names]
    if not groups:
        raise ValueError("rate_boxes: no test to draw")
    fig = new_figure((11, 3.3 * len(groups)))
    axes = np.atleast_1d(fig.subplots(len(groups), 1)).ravel()
    rng = np.random.default_rng(0)  # the dots' horizontal spread only
    for ax, (title, names) in zip(axes, groups, strict=True):
        data = [np.asarray(rates.get(n, []), dtype=float) for n in names]
        data = [d[np.isfinite(d)] for d in data]
        pos = np.arange(1, len(names) + 1)
        ax.boxplot(
            [d if d.size else [np.nan] for d in data],
            positions=pos,
            widths=0.5,
            showfliers=False,
            medianprops={"color": "k", "lw": 1.5},
        )
        for p, d in zip(pos, data, strict=True):
            ax.scatter(
                p + rng.uniform(-0.12, 0.12, d.size), d, s=12, color="C0", alpha=0.7, zorder=3
            )
        for p, n in zip(pos, names, strict=True):
            if n in targets:
                ax.hlines(targets[n], p - 0.35, p + 0.35, color="red", lw=1.5, ls="--", zorder=4)
        # the panel's title says which trials: the names without "agree " and the suffix
        labels = [_short(n) for n in names]
        long = max((len(x) for x in labels), default=0) > 12
        ax.set_xticks(
            pos, labels, fontsize=8, rotation=20 if long else 0, ha="right" if long else "center"
        )
        ax.set_xlim(0.4, max(len(names), 7) + 0.6)
        ax.set_ylim(-0.03, 1.03)
        ax.set_ylabel("success rate")
        marked = any(n in targets for n in names)
        ax.set_title(
            title + (" (black: median; red dashes: target)" if marked else " (black: median)")
        )
        ax.grid(axis="y", alpha=0.3)
    save_png(fig, path)
