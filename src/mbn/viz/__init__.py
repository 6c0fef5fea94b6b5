"""Pictures (matplotlib, Agg): mazes, robot episodes, animated GIFs, the multiplier's error map,
the figures of a run report (:mod:`~mbn.viz.runs`). The only package of ``mbn`` that imports
matplotlib.

* :mod:`~mbn.viz.style` — :func:`~mbn.viz.style.new_figure` and :func:`~mbn.viz.style.save_png`,
  the one way every picture makes a figure and writes a PNG;
* :mod:`~mbn.viz.maze` — :func:`draw_maze`, :func:`save_maze_png`;
* :mod:`~mbn.viz.episodes` — :func:`draw_trajectory`, :func:`plot_episodes`, :class:`EpisodeView`;
* :mod:`~mbn.viz.animate` — :func:`animate_episode`;
* :mod:`~mbn.viz.multiplier` — :func:`plot_multiplier_error`;
* :mod:`~mbn.viz.controllers` — :func:`draw_controller`, :func:`save_controller_png`: a
  controller of any registered kind.

The picture functions are importable from here; their modules (and matplotlib) are imported on
first use, so ``import mbn.viz`` costs nothing.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from mbn.viz.animate import animate_episode
    from mbn.viz.controllers import draw_controller, save_controller_png
    from mbn.viz.episodes import EpisodeView, draw_trajectory, plot_episodes
    from mbn.viz.maze import draw_maze, save_maze_png
    from mbn.viz.multiplier import plot_multiplier_error

__all__ = [
    "EpisodeView",
    "animate_episode",
    "draw_controller",
    "draw_maze",
    "draw_trajectory",
    "plot_episodes",
    "plot_multiplier_error",
    "save_controller_png",
    "save_maze_png",
]

_HOMES = {
    "draw_maze": "mbn.viz.maze",
    "save_maze_png": "mbn.viz.maze",
    "draw_trajectory": "mbn.viz.episodes",
    "plot_episodes": "mbn.viz.episodes",
    "EpisodeView": "mbn.viz.episodes",
    "animate_episode": "mbn.viz.animate",
    "plot_multiplier_error": "mbn.viz.multiplier",
    "draw_controller": "mbn.viz.controllers",
    "save_controller_png": "mbn.viz.controllers",
}


def __getattr__(name: str) -> Any:
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
