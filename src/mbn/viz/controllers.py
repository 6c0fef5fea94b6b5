"""A picture of a controller, by its kind (:mod:`mbn.controllers.kinds`): one heat map per array
its kind names (:meth:`ControllerKind.weights <mbn.controllers.kinds.ControllerKind.weights>`:
weights, biases, programs), or, for a kind that names none, a panel of text (its kind and its
spec's fields). Its episodes are drawn as any controller's (:mod:`mbn.viz.episodes`).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mbn.controllers import kind_of
from mbn.errors import MbnInputError
from mbn.viz.style import new_figure, save_png

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["MAX_TEXT", "controller_text", "draw_controller", "save_controller_png"]

#: The most characters of one field's value the text panel shows.
MAX_TEXT = 60
#: Cells of a heat map up to which each value is written in its cell.
_ANNOTATE_UP_TO = 64


def controller_text(spec: Any) -> list[str]:
    """The lines of the text panel of a spec: its kind, then its fields (those of a dataclass;
    else its type), each value cut to :data:`MAX_TEXT` characters."""
    kind = kind_of(spec)
    lines = [f"kind: {kind.name if kind is not None else '(not registered)'}"]
    if dataclasses.is_dataclass(spec) and not isinstance(spec, type):
        for f in dataclasses.fields(spec):
            text = " ".join(repr(getattr(spec, f.name)).split())
            if len(text) > MAX_TEXT:
                text = text[: MAX_TEXT - 3] + "..."
            lines.append(f"{f.name}: {text}")
    else:
        lines.append(f"a {type(spec).__name__}")
    return lines


def _heat_map(ax: Axes, name: str, values: np.ndarray) -> Any:
    a = np.asarray(values, np.float64)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.size == 0:
        raise MbnInputError(f"{name}: a picture shows 1-D or 2-D arrays, got shape {a.shape}")
    finite = a[np.isfinite(a)]
    bound = float(np.max(np.abs(finite))) if finite.size else 1.0
    bound = bound if bound > 0 else 1.0
    image = ax.imshow(a, cmap="RdBu_r", vmin=-bound, vmax=bound, aspect="auto")
    ax.set_title(f"{name} {a.shape[0]}x{a.shape[1]}", fontsize=9)
    ax.set_xticks(range(a.shape[1]))
    ax.set_yticks(range(a.shape[0]))
    ax.tick_params(labelsize=7)
    if a.size <= _ANNOTATE_UP_TO:
        for (i, j), v in np.ndenumerate(a):
            dark = np.isfinite(v) and abs(v) > 0.6 * bound
            ax.text(
                j,
                i,
                f"{v:.3g}",
                ha="center",
                va="center",
                fontsize=6,
                color="white" if dark else "black",
            )
    return image


def draw_controller(spec: Any, title: str | None = None) -> Figure:
    """A figure of ``spec``: one heat map per array its kind names (diverging colours, 0 white,
    the values written in the cells of a small one), or a panel of text
    (:func:`controller_text`) for a kind that names none. A spec of no registered kind is
    refused."""
    kind = kind_of(spec)
    if kind is None:
        raise MbnInputError(f"not a controller spec of a registered kind: {type(spec).__name__}")
    arrays = dict(kind.weights(spec))
    heading = title or kind.name
    if not arrays:
        lines = controller_text(spec)
        fig = new_figure((6.0, 0.6 + 0.22 * len(lines)))
        ax = fig.add_subplot()
        ax.axis("off")
        ax.text(0.0, 1.0, "\n".join(lines), va="top", ha="left", family="monospace", fontsize=8)
        ax.set_title(f"{heading} (no picture of its own)", fontsize=10)
        return fig
    cols = min(3, len(arrays))
    rows = math.ceil(len(arrays) / cols)
    fig = new_figure((3.6 * cols, 3.0 * rows))
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    for ax, (name, values) in zip(axes, arrays.items(), strict=False):
        image = _heat_map(ax, name, values)
        fig.colorbar(image, ax=ax, shrink=0.8)
    for ax in axes[len(arrays) :]:
        ax.axis("off")
    fig.suptitle(heading)
    return fig


def save_controller_png(spec: Any, path: str | Path, title: str | None = None) -> None:
    """Write :func:`draw_controller` of ``spec`` as a PNG (atomically)."""
    save_png(draw_controller(spec, title), path)
