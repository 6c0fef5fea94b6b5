"""The multiplier's error map: absolute and relative error over the unit square (matplotlib, Agg).

The figure is made and written (a PNG, atomically) by :mod:`mbn.viz.style`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from mbn.networks.multiplier import Multiplier, dense_grid, multiply
from mbn.viz.style import new_figure, save_png

__all__ = ["draw_multiplier_error", "plot_multiplier_error"]


def plot_multiplier_error(
    mul: Multiplier,
    path: str | Path,
    *,
    metrics: dict[str, Any] | None = None,
    validation: np.ndarray | None = None,
    grid_points: int = 101,
) -> None:
    """Heat maps of the absolute and relative error of ``mul`` over [0, 1]^2
    (:func:`draw_multiplier_error` of its outputs on a ``grid_points`` x ``grid_points`` grid).
    Optional validation pairs are drawn as dots (white: within 5 %, red: not)."""
    grid = np.asarray(dense_grid(grid_points))
    output = np.asarray(multiply(mul, grid))
    v_out = None if validation is None else np.asarray(multiply(mul, validation))
    draw_multiplier_error(
        grid,
        output,
        path,
        num_neurons=mul.num_neurons,
        metrics=metrics,
        validation=validation,
        validation_output=v_out,
    )


def draw_multiplier_error(
    grid: np.ndarray,
    output: np.ndarray,
    path: str | Path,
    *,
    num_neurons: int,
    metrics: dict[str, Any] | None = None,
    validation: np.ndarray | None = None,
    validation_output: np.ndarray | None = None,
) -> None:
    """Heat maps of a multiplier's error from its ``output (G*G,)`` on a square ``grid (G*G, 2)``
    (:func:`mbn.networks.multiplier.dense_grid`).

    Left: ``|out - x1 x2|``; right: ``|out - x1 x2| / (x1 x2)`` on a log colour scale with the
    5 % contour; validation pairs (with their outputs) as dots (white: within 5 %, red: not).
    """
    from matplotlib.colors import LogNorm

    grid_points = round(float(np.sqrt(len(grid))))
    out = np.asarray(output).reshape(grid_points, grid_points)
    x = grid[:, 0].reshape(grid_points, grid_points)
    y = grid[:, 1].reshape(grid_points, grid_points)
    target = x * y
    abs_err = np.abs(out - target)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel_err = np.where(target > 0, abs_err / np.where(target > 0, target, 1), np.nan)

    fig = new_figure((11, 4.6), layout=None)  # placed by gridspec, cropped when saved
    ax_abs, ax_rel = fig.subplots(1, 2, gridspec_kw={"wspace": 0.35})
    extent = (0, 1, 0, 1)
    im = ax_abs.imshow(abs_err.T, origin="lower", extent=extent, cmap="viridis")
    fig.colorbar(im, ax=ax_abs, label="|output - x1·x2|")
    ax_abs.set_title(f"absolute error (max {abs_err.max():.3f})")
    im = ax_rel.imshow(
        np.clip(rel_err.T, 1e-4, 10),
        origin="lower",
        extent=extent,
        cmap="magma",
        norm=LogNorm(1e-4, 10),
    )
    fig.colorbar(im, ax=ax_rel, label="|output - x1·x2| / (x1·x2)")
    ax_rel.contour(
        x, y, np.nan_to_num(rel_err, nan=10), levels=[0.05], colors="cyan", linewidths=1.2
    )
    ax_rel.set_title("relative error (cyan: 5 % contour)")
    if validation is not None and validation_output is not None:
        v_out = validation_output
        v_t = validation[:, 0] * validation[:, 1]
        ok = np.abs(v_out - v_t) <= 0.05 * v_t
        for ax in (ax_abs, ax_rel):
            ax.scatter(*validation[ok].T, s=9, c="white", edgecolors="black", linewidths=0.4)
            ax.scatter(*validation[~ok].T, s=12, c="red", edgecolors="black", linewidths=0.4)
    for ax in (ax_abs, ax_rel):
        ax.set_xlabel("x1")
        ax.set_ylabel("x2")
    title = f"{num_neurons}-neuron multiplier"
    if metrics:
        title += (
            f": {metrics['fraction_within_5pct']:.0%} of validation pairs within 5 %, "
            f"fixed point {'ok' if metrics['fixed_point']['passed'] else 'FAILED'}"
        )
    fig.suptitle(title)
    save_png(fig, path, tight=True)
