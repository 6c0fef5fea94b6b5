"""The switch between two programs: behaviour and equilibria along alpha."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from mbn.viz.style import new_figure, save_png

__all__ = ["interpolation_figure", "share_over_runs"]

#: Probes drawn in the equilibria panel (the junctions with a choice), with their colours.
_PROBES = (("LSR", "C0"), ("LR", "C1"), ("LS", "C2"), ("SR", "C3"))


def interpolation_figure(pairs: dict[str, Any], path: Path) -> None:
    """One column per pair of programs (``InterpolationResult.pairs``): above, the share of the
    junction passes where the two rules differ that take P1's exit, the trials passing by each
    rule and the stalled ones, against alpha; below, the turn command ``w`` of every equilibrium
    of the network P(alpha) decodes to at the centre of the crossroads with a choice (filled:
    stable, hollow: unstable; positive turns left)."""
    names = list(pairs)
    has_eq = any(p.points and p.points[0].equilibria for p in pairs.values())
    rows = 2 if has_eq else 1
    fig = new_figure((3.6 * len(names) + 0.6, 3.0 * rows + 0.6))
    axes = fig.subplots(rows, len(names), squeeze=False, sharex=True)
    for c, name in enumerate(names):
        pair = pairs[name]
        alphas = [pt.alpha for pt in pair.points]
        ax = axes[0][c]
        share = [pt.first_share for pt in pair.points]
        ax.plot(alphas, [100 * s if s is not None else float("nan") for s in share], "k-", lw=2,
                label=f"{pair.first}'s exit (where they differ)")  # fmt: skip
        for key, label, colour in (
            ("as_first", f"passes as {pair.first}", "C0"),
            ("as_second", f"passes as {pair.second}", "C3"),
            ("stalled", "stalled", "0.5"),
        ):
            rate = [100 * getattr(pt, key) / max(pt.trials, 1) for pt in pair.points]
            ax.plot(alphas, rate, color=colour, lw=1, ls="--" if key == "stalled" else "-",
                    label=label)  # fmt: skip
        if pair.alpha_half is not None:
            ax.axvline(pair.alpha_half, color="k", lw=0.6, ls=":")
        ax.set_ylim(-3, 103)
        ax.set_title(f"{pair.first} (α=1) : {pair.second} (α=0)", fontsize=9)
        ax.legend(fontsize=6, loc="center left", frameon=False)
        if c == 0:
            ax.set_ylabel("%")
        if rows == 2:
            ax = axes[1][c]
            for probe, colour in _PROBES:
                for stable in (True, False):
                    xs, ys = [], []
                    for pt in pair.points:
                        for e in (pt.equilibria or {}).get(probe, []):
                            if e.stable == stable:
                                xs.append(pt.alpha)
                                ys.append(e.w)
                    ax.scatter(xs, ys, s=14, marker="o",
                               facecolors=colour if stable else "none", edgecolors=colour,
                               label=f"{probe}" if stable else None)  # fmt: skip
            ax.axhline(0, color="0.6", lw=0.6)
            ax.set_ylim(-1.05, 1.05)
            ax.set_xlabel("α")
            if c == 0:
                ax.set_ylabel("w at equilibrium (rad/s, + left)")
                ax.legend(fontsize=6, title="crossroad", title_fontsize=6, frameon=False)
        else:
            ax.set_xlabel("α")
    fig.suptitle("Programs P(α) = α P1 + (1 − α) P2 through the fixed interpreter")
    save_png(fig, path)


def share_over_runs(runs: dict[int, dict[str, Any]], path: Path) -> None:
    """One panel per pair: every run's share of P1's exits at the differing junction passes
    along alpha (thin), and their median (thick); ``runs`` maps a seed to its results'
    ``pairs`` (:func:`mbn.experiments.switch.over_runs.brief`)."""
    import numpy as np

    names = list(dict.fromkeys(name for pairs in runs.values() for name in pairs))
    fig = new_figure((3.6 * max(len(names), 1) + 0.6, 3.4))
    axes = fig.subplots(1, max(len(names), 1), squeeze=False)[0]
    for ax, name in zip(axes, names, strict=False):
        curves = []
        for _, pairs in sorted(runs.items()):
            if name not in pairs:
                continue
            b = pairs[name]
            share = [np.nan if s is None else 100 * s for s in b["first_share"]]
            ax.plot(b["alphas"], share, color="0.6", lw=0.7)
            curves.append((b["alphas"], share))
        if curves and all(c[0] == curves[0][0] for c in curves):
            median = np.nanmedian(np.array([c[1] for c in curves]), axis=0)
            ax.plot(curves[0][0], median, color="k", lw=2, label=f"median of {len(curves)} runs")
            ax.legend(fontsize=7, frameon=False, loc="upper left")
        first, second = name.split(":")
        ax.set_title(f"{first} (α=1) : {second} (α=0)", fontsize=9)
        ax.set_xlabel("α")
        ax.set_ylim(-3, 103)
    axes[0].set_ylabel("P1's exit where the rules differ (%)")
    fig.suptitle("The switch between programs, every run")
    save_png(fig, path)
