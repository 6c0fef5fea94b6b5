"""The ablations of the program path as one bar chart."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from mbn.viz.style import new_figure, save_png

__all__ = ["ablation_bars"]

_BARS = (
    ("MBN, jittered", lambda r: r["mbn_jitter"]["rate"]),
    ("MBN, held-out", lambda r: r["mbn_heldout"]["rate"]),
    ("IM agrees with RF", lambda r: r.get("agreement", {}).get("rf_jitter")),
    ("IM agrees with LF", lambda r: r.get("agreement", {}).get("lf_jitter")),
)


def ablation_bars(rows: Mapping[str, Mapping[str, Any]], path: Path) -> None:
    """One group of bars per ablation: the MBN's success on the jittered and held-out tests and
    the interpreter's agreement with RF and LF on the jittered test (missing where the ablation
    leaves the interpreter as run); the MBN's Wilson intervals as error bars."""
    names = list(rows)
    fig = new_figure((max(8.0, 1.1 * len(names) + 2), 4.2))
    ax = fig.subplots()
    width = 0.2
    x = np.arange(len(names))
    for k, (label, value) in enumerate(_BARS):
        vals = [value(rows[n]) for n in names]
        heights = [100 * v if v is not None else 0.0 for v in vals]
        err = None
        if k < 2:
            key = "mbn_jitter" if k == 0 else "mbn_heldout"
            lo = [
                max(0.0, 100 * (rows[n][key]["rate"] - rows[n][key]["wilson95"][0])) for n in names
            ]
            hi = [
                max(0.0, 100 * (rows[n][key]["wilson95"][1] - rows[n][key]["rate"])) for n in names
            ]
            err = [lo, hi]
        bars = ax.bar(x + (k - 1.5) * width, heights, width, label=label, color=f"C{k}", yerr=err,
                      capsize=2)  # fmt: skip
        for b, v in zip(bars, vals, strict=True):
            if v is None:
                b.set_alpha(0.0)
    ax.set_xticks(x, [n.replace("_", " ") for n in names], rotation=20, ha="right")
    ax.axhline(95, color="0.5", lw=0.8, ls=":")
    ax.set_ylim(0, 105)
    ax.set_ylabel("%")
    ax.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), fontsize=8, ncol=4, frameon=False)
    fig.suptitle("Ablations of the program path (MBN: 95 % Wilson intervals)")
    save_png(fig, path)
