"""Pictures of how controllers carry to mazes drawn from their family
(``docs/generalization.md``): the performance profile over a split's mazes."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from mbn.stats import performance_profile as profile
from mbn.viz.style import new_figure, save_png

__all__ = ["performance_profile", "performance_profile_panels"]


def performance_profile(
    curves: Mapping[str, Sequence[float]],
    path: Path,
    title: str,
    *,
    target: float = 0.95,
    share: float = 0.90,
) -> None:
    """One curve per name: the fraction of the split's mazes (y) whose success rate reaches at
    least x; ``curves`` maps a name to its mazes' success rates. The targets are drawn: a maze
    passes at ``target``, and ``share`` of the mazes must."""
    fig = new_figure(figsize=(6.4, 4.0))
    ax = fig.add_subplot(1, 1, 1)
    xs = np.linspace(0.0, 1.0, 201)
    # a line style per curve too: a controller and the interpreter running its program often
    # draw the same steps, one over the other
    styles = ("-", "--", "-.", ":")
    for k, (name, rates) in enumerate(curves.items()):
        ys = profile(rates, xs)["fraction"]
        label = f"{name} ({len(rates)} mazes)"
        ax.step(xs, ys, where="post", label=label, lw=1.4, ls=styles[k % len(styles)])
    ax.axvline(target, color="0.4", ls=":", lw=1)
    ax.axhline(share, color="0.4", ls=":", lw=1)
    ax.plot([target], [share], "o", color="0.3", ms=4)
    ax.annotate(
        f"target: {share:.0%} of mazes at >= {target:.0%}",
        (target, share),
        xytext=(-8, -14),
        textcoords="offset points",
        ha="right",
        fontsize=8,
        color="0.3",
    )
    ax.set_xlim(0.0, 1.005)
    ax.set_ylim(0.0, 1.02)
    ax.set_xlabel("success rate x")
    ax.set_ylabel("fraction of mazes at >= x")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8, loc="lower left")
    ax.grid(alpha=0.3)
    save_png(fig, path)


def performance_profile_panels(
    profiles: Mapping[str, Mapping[str, Sequence[float]]],
    path: Path,
    *,
    target: float = 0.95,
    share: float = 0.90,
) -> None:
    """One panel per controller (``profiles``: controller -> curve name -> its mazes' success
    rates), each a performance profile (:func:`performance_profile`) with a curve per name."""
    n = len(profiles)
    cols = min(n, 3)
    rows = (n + cols - 1) // cols
    fig = new_figure(figsize=(4.2 * cols, 3.3 * rows))
    xs = np.linspace(0.5, 1.0, 201)
    for k, (name, curves) in enumerate(profiles.items()):
        ax = fig.add_subplot(rows, cols, k + 1)
        for label, rates in curves.items():
            ys = profile(rates, xs)["fraction"]
            ax.step(xs, ys, where="post", lw=1.0, alpha=0.8, label=label)
        ax.axvline(target, color="0.4", ls=":", lw=1)
        ax.axhline(share, color="0.4", ls=":", lw=1)
        ax.set_xlim(0.5, 1.005)
        ax.set_ylim(0.0, 1.02)
        ax.set_title(name, fontsize=10)
        ax.set_xlabel("success rate x", fontsize=8)
        ax.set_ylabel("mazes at >= x", fontsize=8)
        ax.grid(alpha=0.3)
        if k == 0:
            ax.legend(fontsize=6, loc="lower left", ncol=2)
    save_png(fig, path)
