"""Pictures of a run of ``mbn reproduce``, drawn from what the run folder records (stage data,
``records/*.npz``): nothing here simulates.

* :func:`de_curves` — DE fitness per generation of RF, LF and PM, and the LF search's choice;
* :func:`test_trajectories` — one figure per test: the paper-protocol trials on the maze;
* :func:`mbn_traces` — one MBN episode: camera, program, interpreter, motors around switches;
* :func:`mbn_animation` — the same episode as a GIF.

The multiplier's error map is :func:`mbn.viz.multiplier.draw_multiplier_error`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mbn.notation import connection_name, connection_names
from mbn.viz.animate import animate_episode
from mbn.viz.episodes import plot_episodes
from mbn.viz.style import new_figure, save_png
from mbn.world.mazes.model import Maze

__all__ = ["de_curves", "mbn_animation", "mbn_traces", "test_trajectories"]


def de_curves(stages: dict[str, Any], path: Path) -> None:
    """DE best and mean fitness per generation of RF, LF and PM, and the LF search's choice."""
    fig = new_figure((11, 7.5), layout=None)
    axes = fig.subplots(2, 2)
    for ax, (name, title) in zip(
        (axes[0, 0], axes[1, 0], axes[1, 1]),
        (("rf", "RF (12 genes)"), ("lf", "LF (3 genes)"), ("pm", "PM (program module)")),
        strict=True,
    ):
        h = stages[name]["history"]
        g = np.arange(len(h["best"]))
        chosen = stages[name].get("chosen_restart")
        for r, other in enumerate(stages[name].get("restarts", [])):
            if r != chosen:
                ax.plot(
                    np.arange(len(other["history"]["best"])),
                    other["history"]["best"],
                    color="C0",
                    alpha=0.35,
                    lw=1,
                    label=f"best, restart {r + 1} (not kept)",
                )
        ax.plot(g, h["best"], label="best", color="C0")
        ax.plot(g, h["mean"], label="population mean", color="C1", alpha=0.8)
        programs = name == "pm" and stages[name].get("reward") == "programs"
        if name == "pm":
            ax.axhline(stages[name]["max_fitness"], color="grey", ls="--", lw=1, label="maximum")
        ax.set_title(f"{title}: DE " + ("program reward" if programs else "fitness"))
        ax.set_xlabel("generation")
        ax.set_ylabel("program reward (0 at best)" if programs else "fitness")
        ax.legend(loc="lower right", fontsize=8)
    ax = axes[0, 1]
    rows = stages["lf_search"]["triples"]
    chosen = stages["lf_search"]["chosen"]
    fit = [r["best_fitness"] for r in rows]
    robust = [r.get("robust_fitness", np.nan) for r in rows]
    labels = [connection_names(r["connections"]) for r in rows]
    colors = ["C2" if r["connections"] == chosen else "C7" for r in rows]
    y = np.arange(len(rows))
    ax.barh(y, robust, color=colors, height=0.6, label="choice score: perturbed copies, corners")
    ax.barh(y, fit, color="none", edgecolor="k", lw=0.8, zorder=3, label="search's best fitness")
    ax.set_yticks(y, labels, fontsize=6)
    ax.invert_yaxis()
    ax.set_xlabel("left-rule fitness")
    ax.legend(loc="lower right", fontsize=7)
    ax.set_title("LF: which 3 connections to re-evolve (green: chosen)")
    fig.tight_layout()
    save_png(fig, path, dpi=100, tight=True)


def test_trajectories(
    maze: Maze,
    trajectory: Any,
    details: dict[str, list[Any]],
    title: str,
    path: Path,
) -> None:
    """The paper-protocol trials of one test on ``maze``, one panel per start mark (``details``:
    per trial ``success``, ``correct``, ``judged``, ``stall``)."""
    n = len(details["success"])
    titles = [
        f"start {k + 1}: {'ok' if details['success'][k] else 'FAIL'} "
        f"({details['correct'][k]}/{details['judged'][k]}, stall {details['stall'][k]:.1%})"
        for k in range(n)
    ]
    fig = plot_episodes(maze, trajectory, list(range(n)), titles=titles, ncols=5, title=title)
    save_png(fig, path, dpi=70)  # the constrained layout fits it: no second, tight pass


def mbn_traces(
    recording: dict[str, np.ndarray],
    connections: Sequence[str],
    programs: Mapping[str, Sequence[float]],
    path: Path,
) -> None:
    """Camera, program, interpreter firing rates and motor commands of one recorded MBN episode
    (``records/mbn_recording.npz``), with lines where the tile in force changes; ``programs``:
    the stored RF and LF programs (``right``, ``left``) drawn as reference lines."""
    b = int(recording["start_mark"])
    program, rates = recording["program"], recording["rates"]
    t, camera, tile = recording["t"], recording["camera"], recording["tile"]
    fig = new_figure((11, 7), layout=None)
    ax = fig.subplots(4, 1, sharex=True, gridspec_kw={"height_ratios": [1, 2, 2, 1.4]})
    ax[0].step(t, camera, where="post", color="C7", label="camera (tile in view)")
    ax[0].step(t, tile, where="post", color="C3", lw=2, label="tile in force (driven over)")
    ax[0].set_yticks([0, 1, 2], ["none", "1 colour", "2 colours"])
    ax[0].legend(loc="upper right", fontsize=8)
    for k in range(program.shape[1]):
        ax[1].plot(
            t,
            program[:, k],
            label=f"program {k + 1} ({connection_name(connections[k])})",
            color=f"C{k}",
        )
    for name, style in (("right", ":"), ("left", "--")):
        for k, v in enumerate(programs[name]):
            ax[1].axhline(v, color=f"C{k}", ls=style, lw=0.8, alpha=0.6)
    ax[1].set_ylabel("PM output")
    ax[1].set_ylim(-0.05, 1.05)
    ax[1].legend(loc="center right", fontsize=8, title="dotted: RF program, dashed: LF", ncol=3)
    for k in range(rates.shape[1]):
        ax[2].plot(t, rates[:, k], label=f"neuron {k + 1}", color=f"C{k + 3}")
    ax[2].set_ylabel("IM firing rate")
    ax[2].legend(loc="upper right", fontsize=8, ncol=3)
    ax[3].plot(t, recording["v"], label="v (m/s)", color="C0")
    ax[3].plot(t, recording["w"], label="omega (rad/s)", color="C1")
    ax[3].set_xlabel("time (s)")
    ax[3].legend(loc="upper right", fontsize=8, ncol=2)
    switches = [int(i) + 1 for i in np.flatnonzero(np.diff(tile) != 0)]
    for a in ax:
        for i in switches:
            a.axvline(t[i], color="C3", lw=0.8, alpha=0.5)
    ax[0].set_title(
        f"MBN from start mark {b + 1}: camera, program, interpreter and motors "
        "(red lines: tile in force changes)"
    )
    fig.tight_layout()
    save_png(fig, path, dpi=100, tight=True)


def mbn_animation(
    maze: Maze,
    recording: dict[str, np.ndarray],
    sonars: Sequence[int],
    camera_fov_deg: float,
    camera_range: float,
    path: Path,
) -> None:
    """The recorded MBN episode as an animated GIF."""
    b = int(recording["start_mark"])
    animate_episode(
        maze,
        recording["pose"],
        path,
        ranges=recording["ranges"],
        sonars=sonars,
        camera=recording["camera"],
        tile=recording["tile"],
        stalled=recording["stalled"],
        t=recording["t"],
        fps=15.0,
        max_frames=150,
        dpi=60,
        title=f"MBN from start mark {b + 1}",
        camera_fov_deg=camera_fov_deg,
        camera_range=camera_range,
    )
