"""Programs against dynamics: one run's contenders over its budget, and, over runs, the
fraction of runs solved against evaluations."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mbn.viz.style import new_figure, save_png

__all__ = ["CONTENDER_COLORS", "contest_checks", "solved_curves"]

#: One colour per contender, the same in every picture.
CONTENDER_COLORS = {"programs": "C0", "scratch": "C3", "neighbour": "C2", "monolithic": "C4"}


def contest_checks(runs: Mapping[str, Mapping[str, Mapping[str, Any]]], path: Path) -> None:
    """One panel per rule: each contender's best fitness per check against evaluations, a
    filled marker where that best passed the test (every mark and the jittered target), an
    empty one where it did not; a vertical line at its evaluations to success."""
    rules = list(runs)
    fig = new_figure((5.2 * len(rules), 3.8))
    axes = np.atleast_1d(fig.subplots(1, len(rules), squeeze=False)[0])
    for ax, rule in zip(axes, rules, strict=True):
        for who, d in runs[rule].items():
            color = CONTENDER_COLORS.get(who, "C7")
            e = [c["evaluations"] for c in d["checks"]]
            f = [c["best_fitness"] for c in d["checks"]]
            ok = np.asarray([c["success"] for c in d["checks"]])
            ax.plot(e, f, color=color, lw=1.2, label=who)
            ax.plot(np.asarray(e)[ok], np.asarray(f)[ok], "o", color=color, ms=4)
            ax.plot(
                np.asarray(e)[~ok], np.asarray(f)[~ok], "o", mfc="none", color=color, ms=4, mew=0.8
            )
            if d["evaluations"] is not None:
                ax.axvline(d["evaluations"], color=color, ls=":", lw=1)
        ax.set_title(f"{rule}: best fitness (filled: passes the test)")
        ax.set_xlabel("evaluations")
        ax.set_ylabel("crossroad fitness")
        ax.legend(fontsize=8, loc="lower right")
    save_png(fig, path, dpi=90)


def solved_curves(
    curves: Mapping[str, Mapping[str, tuple[Sequence[float], Sequence[float], int]]],
    budget: float,
    path: Path,
) -> None:
    """One panel per rule: for each contender the fraction of runs whose best had passed the
    test within ``e`` evaluations (a step per run; ``curves[rule][who] = (e, fraction, runs)``)."""
    rules = list(curves)
    fig = new_figure((5.2 * len(rules), 3.8))
    axes = np.atleast_1d(fig.subplots(1, len(rules), squeeze=False)[0])
    for ax, rule in zip(axes, rules, strict=True):
        for who, (e, frac, n) in curves[rule].items():
            ax.step(
                e,
                frac,
                where="post",
                color=CONTENDER_COLORS.get(who, "C7"),
                label=f"{who} ({n} run{'s' * (n != 1)})",
            )
        ax.set_xlim(0, budget)
        ax.set_ylim(-0.02, 1.02)
        ax.set_title(f"{rule}: runs solved")
        ax.set_xlabel("evaluations")
        ax.set_ylabel("fraction of runs")
        ax.legend(fontsize=8, loc="upper left")
    save_png(fig, path, dpi=90)
