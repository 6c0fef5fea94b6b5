"""Former home of the maze and episode pictures, kept only for code not yet moved.

The pictures now live in :mod:`mbn.viz.maze`, :mod:`mbn.viz.episodes` and :mod:`mbn.viz.animate`
(all re-exported by :mod:`mbn.viz`); this module re-exports the three names still imported from
here and goes once nothing does.
"""

from mbn.viz.animate import animate_episode
from mbn.viz.episodes import EpisodeView, plot_episodes

__all__ = ["EpisodeView", "animate_episode", "plot_episodes"]
