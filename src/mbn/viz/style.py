"""The one way every picture of :mod:`mbn.viz` makes a figure and writes it.

* :func:`new_figure` — a :class:`~matplotlib.figure.Figure` made directly (never through
  ``pyplot``) with its own Agg canvas, so nothing changes matplotlib's global state or backend
  and it works headless;
* :func:`save_png` — the figure written as a PNG on a white background, atomically (a temporary
  file in the same folder, then a rename: :func:`mbn.io.atomic_open`).

Figures are made at :data:`DPI` dots per inch and saved at their own dpi unless told otherwise,
so :data:`DPI` is the resolution of every PNG. matplotlib is imported when the first figure is
made, not when this module is.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from mbn.io import atomic_open

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["DPI", "new_figure", "save_png"]

#: Dots per inch of new figures, and so of every PNG written (a fig4 maze: 1050 px wide).
DPI = 150.0


def new_figure(
    figsize: tuple[float, float],
    dpi: float = DPI,
    *,
    layout: Literal["constrained"] | None = "constrained",
) -> Figure:
    """A new Figure ``figsize`` inches at ``dpi``, drawn by its own Agg canvas.

    ``layout="constrained"`` (the default) lets matplotlib fit titles, labels and legends inside
    the figure; ``None`` leaves the axes where they are put (save with ``tight=True`` then).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=dpi, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def save_png(
    fig: Figure,
    path: str | os.PathLike[str],
    dpi: float | None = None,
    *,
    tight: bool = False,
) -> None:
    """Write ``fig`` to ``path`` as a PNG on white, atomically.

    Args:
        fig: the figure.
        path: the file to write (its folder must exist).
        dpi: dots per inch; None: the figure's own (:data:`DPI` for :func:`new_figure`'s).
        tight: crop the picture to what is drawn (``bbox_inches="tight"``), for figures made
            without a layout.
    """
    with atomic_open(Path(path), "wb") as handle:
        fig.savefig(
            handle,
            format="png",
            dpi=fig.dpi if dpi is None else dpi,
            facecolor="white",
            bbox_inches="tight" if tight else None,
        )
