"""MBNs of K behaviours: success, forgetting and code error against K."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from mbn.viz.style import new_figure, save_png

__all__ = ["against_k", "against_k_over_runs"]


def against_k(rows: dict[int, dict[str, Any]], path: Path) -> None:
    """Three panels against K (``rows``: :func:`mbn.experiments.scaling.report.scaling_summary`
    by K): the test split's pooled success and share of mazes at 95 %; forgetting with its
    interval and the ±2-point target; the program module's worst and mean code error."""
    ks = sorted(rows)
    fig = new_figure((11, 3.4))
    a, b, c = fig.subplots(1, 3)
    tested = [k for k in ks if rows[k]["test"]]
    a.plot(tested, [100 * rows[k]["test"]["success_rate"] for k in tested], "o-", label="pooled")
    share = [100 * rows[k]["test"]["mazes_at_95"] / rows[k]["test"]["mazes"] for k in tested]
    a.plot(tested, share, "s--", label="mazes at 95 %")
    a.axhline(95, color="0.5", lw=0.8, ls=":")
    a.set_ylim(0, 102)
    a.set_title("test split", fontsize=9)
    a.set_ylabel("%")
    a.legend(fontsize=7, frameon=False)
    forgot = [k for k in ks if rows[k]["forgetting"]]
    for k in forgot:
        f = rows[k]["forgetting"]
        b.errorbar([k], [f["points"]], yerr=[[f["points"] - f["low"]], [f["high"] - f["points"]]],
                   fmt="o", color="C0", capsize=3)  # fmt: skip
    b.axhspan(-2, 2, color="0.9")
    b.axhline(0, color="0.5", lw=0.6)
    b.set_title("forgetting: change on K - 1's test (points)", fontsize=9)
    c.plot(ks, [rows[k]["code_error_worst"] for k in ks], "o-", label="worst")
    c.plot(ks, [rows[k]["code_error_mean"] for k in ks], "s--", label="mean")
    c.set_ylim(bottom=0)
    c.set_title("program module's code error", fontsize=9)
    c.legend(fontsize=7, frameon=False)
    for ax in (a, b, c):
        ax.set_xlabel("K (behaviours)")
        ax.set_xticks(ks)
    fig.suptitle("MBNs of K behaviours on one fixed interpreter")
    save_png(fig, path)


def against_k_over_runs(runs: dict[int, dict[str, Any]], path: Path) -> None:
    """Two panels against K, one line per run (``runs``: seed -> its results' ``scaling``): the
    test split's pooled success, and forgetting with the ±2-point band."""
    fig = new_figure((9, 3.4))
    a, b = fig.subplots(1, 2)
    for _, rows in sorted(runs.items()):
        ks = sorted(int(k) for k in rows)
        tested = [k for k in ks if rows[str(k)].get("test")]
        a.plot(tested, [100 * rows[str(k)]["test"]["success_rate"] for k in tested],
               "o-", color="0.5", lw=0.8, ms=3)  # fmt: skip
        forgot = [k for k in ks if rows[str(k)].get("forgetting")]
        b.plot(forgot, [rows[str(k)]["forgetting"]["points"] for k in forgot],
               "o-", color="0.5", lw=0.8, ms=3)  # fmt: skip
    a.axhline(95, color="C3", lw=0.8, ls=":")
    a.set_ylim(0, 102)
    a.set_ylabel("test split pooled (%)")
    b.axhspan(-2, 2, color="0.9")
    b.axhline(0, color="0.5", lw=0.6)
    b.set_ylabel("forgetting (points)")
    for ax in (a, b):
        ax.set_xlabel("K (behaviours)")
    fig.suptitle(f"MBNs of K behaviours, {len(runs)} runs")
    save_png(fig, path)
