"""Pictures of a run of ``mbn run new-behaviours``, drawn from its records: an MBN's paths
coloured by the rule in force, and its program module's codes around the tile switches."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from mbn.viz.maze import draw_maze, legend_below
from mbn.viz.style import new_figure, save_png
from mbn.world.mazes.model import Maze

__all__ = ["RULE_COLORS", "code_traces", "rule_paths"]

#: The colour of each rule's stretch of path.
RULE_COLORS: Mapping[str, str] = {
    "right": "#d95f02",
    "left": "#1b66c9",
    "straight-right": "#1a9850",
    "straight-left": "#7b3294",
    "right-left": "#e7298a",
    "left-right": "#66a61e",
}


def _in_force(tile: np.ndarray, rules: Sequence[str], initial: str) -> list[str]:
    return [initial if k <= 0 else rules[int(k) - 1] for k in tile]


def rule_paths(
    maze: Maze,
    pose: np.ndarray,
    tile: np.ndarray,
    rules: Sequence[str],
    initial: str,
    title: str,
    path: Path,
) -> None:
    """Every robot's path ``pose (B, n, 3)`` on ``maze``, each stretch coloured by the rule in
    force there (``tile (B, n)``: colours of the last tile driven over, 0 before the first, when
    ``initial`` holds; a tile of k colours puts ``rules[k - 1]`` in force)."""
    from matplotlib.lines import Line2D

    fig = new_figure((9, 7.5))
    ax = fig.add_subplot()
    draw_maze(maze, ax, junctions=False, title="")
    for b in range(pose.shape[0]):
        force = _in_force(tile[b], rules, initial)
        xy = pose[b, :, :2]
        start = 0
        for i in range(1, len(force) + 1):
            if i == len(force) or force[i] != force[start]:
                seg = xy[start : min(i + 1, len(xy))]
                ax.plot(seg[:, 0], seg[:, 1], color=RULE_COLORS.get(force[start], "k"), lw=1.4)
                start = i
    ax.set_title(title, fontsize=10)
    legend_below(fig, [Line2D([], [], color=RULE_COLORS.get(r, "k"), lw=2, label=r) for r in rules])
    save_png(fig, path)


def code_traces(
    t: np.ndarray, tile: np.ndarray, codes: np.ndarray, rules: Sequence[str], title: str, path: Path
) -> None:
    """One robot's tile in force ``tile (n,)`` and its program module's code neurons
    ``codes (n, K)`` over time, with lines where the tile in force changes."""
    fig = new_figure((10, 4.5))
    ax = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [1, 2]})
    ax[0].step(t, tile, where="post", color="C3")
    ax[0].set_yticks(range(len(rules) + 1), ["none", *[f"{k + 1} col." for k in range(len(rules))]])
    ax[0].set_ylabel("tile in force")
    for k, rule in enumerate(rules):
        ax[1].plot(t, codes[:, k], color=RULE_COLORS.get(rule, f"C{k}"), label=f"code {rule}")
    ax[1].set_ylim(-0.05, 1.05)
    ax[1].set_xlabel("time (s)")
    ax[1].set_ylabel("PM code neuron")
    ax[1].legend(loc="center right", fontsize=8)
    for change in np.flatnonzero(np.diff(tile) != 0):
        for panel in ax:
            panel.axvline(t[int(change) + 1], color="C3", lw=0.8, alpha=0.5)
    ax[0].set_title(title)
    save_png(fig, path)
