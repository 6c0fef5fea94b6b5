"""Pictures of robot episodes: paths, body footprints, stalls and sonar rays (matplotlib, Agg).

* :func:`draw_trajectory` — one robot's path, body footprints, stalls and sonar rays;
* :func:`plot_episodes` — several robots of a rollout batch (small multiples or an overlay);
* :class:`EpisodeView` — a maze with one robot drawn on it, updated in place (the frames of
  :func:`mbn.viz.animate.animate_episode` and of the Gymnasium environment's ``rgb_array``
  rendering).

The maze under them is drawn by :mod:`mbn.viz.maze`; figures are made and saved by
:mod:`mbn.viz.style`. Colours: paths purple (then :data:`PATH_COLORS`), stalls red crosses, sonar
rays teal (solid up to an echo, dotted where a ray reads the 5 m maximum).
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Polygon, Wedge
from numpy.typing import ArrayLike

from mbn.errors import MbnInputError
from mbn.viz.maze import (
    TILE1_COLOR,
    TILE_PALETTES,
    draw_maze,
    legend_below,
    maze_figsize,
    maze_legend_handles,
    root_figure,
)
from mbn.viz.style import new_figure, save_png
from mbn.world.mazes.model import Maze
from mbn.world.robot import BODY, SONAR_MAX_RANGE, SONAR_POSES

__all__ = [
    "PATH_COLORS",
    "RAY_COLOR",
    "STALL_COLOR",
    "EpisodeView",
    "draw_trajectory",
    "plot_episodes",
    "poses_array",
    "sonar_indices",
]

RAY_COLOR = "#0e9f9f"
STALL_COLOR = "#d62728"
#: Colours given to successive robots (the first is the default trajectory colour).
PATH_COLORS = (
    "#5b3fa8",
    "#1f77b4",
    "#8c564b",
    "#e377c2",
    "#17becf",
    "#8a8a1f",
    "#7f7f7f",
    "#222222",
)
_CAMERA_FOV_COLORS = {
    0: "#9aa0a6",
    1: TILE1_COLOR,
    **{n: colors[1] for n, colors in TILE_PALETTES.items() if n > 1},
}
_TILE_WORDS = {0: "none", 1: "1-colour", 2: "2-colour"}


def poses_array(poses: ArrayLike, name: str = "poses") -> np.ndarray:
    """``poses`` as a finite float64 ``(n, 3)`` array with ``n >= 1``, or an error naming them."""
    p = np.asarray(poses, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] < 1:
        raise MbnInputError(f"{name} must have shape (n, 3) with n >= 1, got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise MbnInputError(f"{name} must be finite")
    return p


def sonar_indices(k: int, sonars: Sequence[int] | None) -> tuple[int, ...]:
    """Stage indices of the ``k`` columns of a ranges array: ``sonars`` if given, else all 16
    (k = 16) or the paper's 10 (k = 10)."""
    if sonars is None:
        from mbn.world.sensors import ALL_SONARS, PAPER_SONARS

        if k == len(ALL_SONARS):
            return ALL_SONARS
        if k == len(PAPER_SONARS):
            return PAPER_SONARS
        raise MbnInputError(
            f"ranges have {k} sonars: pass sonars= (their Stage indices, 0..15) to draw them"
        )
    out = tuple(int(s) for s in sonars)
    if len(out) != k or any(not 0 <= s < 16 for s in out):
        raise MbnInputError(
            f"sonars must be {k} Stage indices in 0..15 (one per ranges column), got {out!r}"
        )
    return out


@functools.cache
def _jitted_sonar_rays() -> Callable[..., Any]:
    """:func:`~mbn.world.geometry.sonar_rays`, jitted (an animation calls it once a frame)."""
    import jax

    from mbn.world.geometry import sonar_rays

    return jax.jit(sonar_rays)


def _body(poses: np.ndarray) -> np.ndarray:
    """World-frame body octagons ``(n, 8, 2)`` at ``poses (n, 3)``: the arithmetic of
    :func:`~mbn.world.geometry.body_polygon` in NumPy (a picture needs no compiled program
    for each number of poses)."""
    p = np.asarray(poses, np.float64)
    b = np.asarray(BODY, np.float64)
    x, y, th = p[..., 0:1], p[..., 1:2], p[..., 2:3]
    c, s = np.cos(th), np.sin(th)
    return np.stack([x + c * b[:, 0] - s * b[:, 1], y + s * b[:, 0] + c * b[:, 1]], -1)


def _ray_segments(
    pose: np.ndarray, ranges: np.ndarray, sonars: Sequence[int]
) -> tuple[np.ndarray, np.ndarray]:
    """Segments ``(k, 2, 2)`` from each sonar's origin to where its ray ends, and whether each
    ray met a wall within range ``(k,)``."""
    origins, angles = _jitted_sonar_rays()(pose, SONAR_POSES[list(sonars)])
    o = np.asarray(origins, dtype=np.float64)
    a = np.asarray(angles, dtype=np.float64)
    r = np.asarray(ranges, dtype=np.float64)
    ends = o + r[:, None] * np.stack([np.cos(a), np.sin(a)], -1)
    return np.stack([o, ends], 1), r < SONAR_MAX_RANGE - 1e-6


def _footprint_indices(p: np.ndarray, every: int | None) -> np.ndarray:
    """Samples that get a body footprint: every ``every``-th (0: none), or by default one each
    metre of path (from the first sample); the last sample always gets one."""
    n = p.shape[0]
    if every is not None:
        if every < 0:
            raise MbnInputError(f"footprints_every must be >= 0 or None, got {every!r}")
        idx = np.arange(0, n, every) if every > 0 else np.zeros(0, dtype=int)
    else:
        step = np.hypot(np.diff(p[:, 0]), np.diff(p[:, 1]))
        dist = np.concatenate([[0.0], np.cumsum(step)])
        marks = np.floor(dist / 1.0)
        idx = np.concatenate([[0], np.nonzero(np.diff(marks) > 0)[0] + 1])
    return np.unique(np.concatenate([idx, [n - 1]]))


def _limits_with(ax: Axes, maze: Maze, p: np.ndarray) -> None:
    """For open mazes, grow the axes so that the whole path shows."""
    if maze.outside_is_wall:
        return
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    pad = 0.5
    ax.set_xlim(min(x0, p[:, 0].min() - pad), max(x1, p[:, 0].max() + pad))
    ax.set_ylim(min(y0, p[:, 1].min() - pad), max(y1, p[:, 1].max() + pad))


def draw_trajectory(
    maze: Maze,
    poses: ArrayLike,
    ax: Axes | None = None,
    *,
    color: str | None = None,
    footprints_every: int | None = None,
    sonar_at: Sequence[int] = (),
    ranges: ArrayLike | None = None,
    sonars: Sequence[int] | None = None,
    stalled: ArrayLike | None = None,
    label: str | None = None,
    with_maze: bool | None = None,
    path: str | os.PathLike[str] | None = None,
) -> Figure:
    """Draw one robot's path through ``maze``.

    The path is a line through the poses' ``(x, y)`` (gid ``"path"``); the start is a dot, and
    body octagons (:data:`~mbn.world.robot.BODY`, gid ``"footprint"``) with a heading tick mark
    the pose at intervals and at the end (the last one drawn more strongly). Sonar rays at chosen
    samples run from each transducer's origin to its echo (gid ``"rays"``; dotted where the ray
    reads the 5 m maximum). Stalled samples get red crosses (gid ``"stalls"``).

    Args:
        maze: the maze.
        poses: ``(n, 3)`` poses ``(x, y, theta)``, e.g. ``trajectory.pose[b]`` of a rollout.
        ax: axes to draw on; None makes a new figure.
        color: the path's colour (default the first of :data:`PATH_COLORS`).
        footprints_every: a footprint every that many samples (0: only the last); None: about
            one per metre of path.
        sonar_at: sample indices at which to draw the sonar rays (needs ``ranges``).
        ranges: ``(n, k)`` sonar readings (metres) of the same samples.
        sonars: the Stage indices (0..15) of the ``k`` columns of ``ranges``; None: all 16 for
            k = 16, the paper's 10 (:data:`~mbn.world.sensors.PAPER_SONARS`) for k = 10.
        stalled: ``(n,)`` bool, samples at which the robot was stalled.
        label: legend label of the path.
        with_maze: draw the maze first; None means yes exactly when a new figure is made (a new
            figure also gets a legend below it).
        path: write the figure there as a PNG (atomically).

    Returns:
        The Figure drawn on.
    """
    p = poses_array(poses)
    n = p.shape[0]
    new = ax is None
    if ax is None:
        fig = (
            draw_maze(maze, legend=False)
            if with_maze is not False
            else new_figure(maze_figsize(maze))
        )
        if not fig.axes:
            fig.add_subplot().set_aspect("equal")
        ax = fig.axes[0]
    else:
        fig = root_figure(ax)
        if with_maze:
            draw_maze(maze, ax, legend=False)
    color = PATH_COLORS[0] if color is None else color
    ax.plot(
        p[:, 0],
        p[:, 1],
        color=color,
        lw=1.6,
        label=label,
        zorder=5,
        gid="path",
        solid_capstyle="round",
        solid_joinstyle="round",
    )
    ax.plot(p[0, 0], p[0, 1], "o", color=color, ms=4, zorder=5, gid="path_start")
    idx = _footprint_indices(p, footprints_every)
    bodies = _body(p[idx])
    nose = float(BODY[:, 0].max())
    for j, (k, body) in enumerate(zip(idx, bodies, strict=True)):
        last = j == len(idx) - 1
        ax.add_patch(
            Polygon(
                body,
                closed=True,
                facecolor=color,
                alpha=0.45 if last else 0.16,
                edgecolor=color,
                linewidth=1.2 if last else 0.7,
                zorder=6 if last else 4.5,
                gid="footprint",
            )
        )
        x, y, th = p[k]
        ax.plot(
            [x, x + nose * math.cos(th)],
            [y, y + nose * math.sin(th)],
            color=color,
            lw=1.2 if last else 0.8,
            zorder=6,
            gid="heading",
        )
    if stalled is not None:
        st = np.asarray(stalled, dtype=bool).reshape(-1)
        if st.shape != (n,):
            raise MbnInputError(f"stalled must have shape ({n},), got {st.shape}")
        if st.any():
            ax.plot(
                p[st, 0],
                p[st, 1],
                "x",
                color=STALL_COLOR,
                ms=6,
                mew=1.6,
                zorder=7,
                gid="stalls",
                label="stall",
            )
    sonar_at = [int(i) for i in sonar_at]
    if sonar_at:
        if ranges is None:
            raise MbnInputError("sonar_at needs ranges (n, k)")
        r = np.asarray(ranges, dtype=np.float64)
        if r.ndim != 2 or r.shape[0] != n:
            raise MbnInputError(f"ranges must have shape ({n}, k), got {r.shape}")
        ids = sonar_indices(r.shape[1], sonars)
        for i in sonar_at:
            if not -n <= i < n:
                raise MbnInputError(f"sonar_at index {i} out of range for {n} samples")
            _draw_rays(ax, p[i], r[i], ids)
    _limits_with(ax, maze, p)
    if new and with_maze is not False:
        handles = maze_legend_handles(maze, junctions=True, starts=True, tiles=True)
        handles.append(Line2D([], [], color=color, lw=1.6, label=label or "path"))
        if stalled is not None and np.any(stalled):
            handles.append(
                Line2D([], [], color=STALL_COLOR, marker="x", ls="", mew=1.6, label="stall")
            )
        if sonar_at:
            handles.append(Line2D([], [], color=RAY_COLOR, lw=0.9, label="sonar rays"))
        legend_below(fig, handles)
    if path is not None:
        save_png(fig, path)
    return fig


def _draw_rays(ax: Axes, pose: np.ndarray, ranges: np.ndarray, sonars: Sequence[int]) -> None:
    segs, hit = _ray_segments(pose, ranges, sonars)
    ax.add_collection(
        LineCollection(list(segs[hit]), colors=RAY_COLOR, linewidths=0.9, zorder=5.5, gid="rays")
    )
    ax.add_collection(
        LineCollection(
            list(segs[~hit]),
            colors=RAY_COLOR,
            linewidths=0.8,
            linestyles=":",
            alpha=0.7,
            zorder=5.5,
            gid="rays",
        )
    )
    if hit.any():
        ends = segs[hit, 1]
        ax.plot(ends[:, 0], ends[:, 1], ".", color=RAY_COLOR, ms=4, zorder=5.5, gid="echoes")


def plot_episodes(
    maze: Maze,
    trajectory: Any,
    indices: Sequence[int],
    path: str | os.PathLike[str] | None = None,
    titles: Sequence[str] | None = None,
    *,
    overlay: bool = False,
    sonars: Sequence[int] | None = None,
    footprints_every: int | None = None,
    ncols: int | None = None,
    title: str | None = None,
) -> Figure:
    """Several robots of a rollout batch on one maze.

    By default one panel per robot (small multiples, up to ``ncols`` = 3 a row), each with the
    path, footprints, stalls and the sonar rays at the last sample, titled with the distance
    driven, the duration and the share of stalled samples. ``overlay=True`` draws all paths on one
    maze in different colours instead (footprint at the end only, no rays).

    Args:
        maze: the maze every robot drove in.
        trajectory: a :class:`~mbn.world.rollout.Trajectory` (or anything with ``pose (B, n, 3)``
            and optionally ``stalled (B, n)``, ``ranges (B, n, k)``, ``t (n,)``).
        indices: which robots of the batch to draw.
        path: write the figure there as a PNG (atomically).
        titles: one title per robot (default: robot index and statistics).
        overlay: all robots on one axes.
        sonars: Stage indices of the ranges' columns (see :func:`draw_trajectory`); rays are
            skipped when they cannot be told.
        footprints_every: as in :func:`draw_trajectory`.
        ncols: panels per row.
        title: the figure's title (default: the maze's name).

    Returns:
        The Figure.
    """
    pose = np.asarray(trajectory.pose, dtype=np.float64)
    if pose.ndim != 3 or pose.shape[-1] != 3:
        raise MbnInputError(f"trajectory.pose must have shape (B, n, 3), got {pose.shape}")
    b = pose.shape[0]
    idx = [int(i) for i in indices]
    if not idx:
        raise MbnInputError("plot_episodes needs at least one index")
    for i in idx:
        if not 0 <= i < b:
            raise MbnInputError(f"index {i} out of range for a batch of {b}")
    if titles is not None and len(titles) != len(idx):
        raise MbnInputError(f"titles: expected {len(idx)}, got {len(titles)}")
    stalled = getattr(trajectory, "stalled", None)
    st = None if stalled is None else np.asarray(stalled, dtype=bool)
    ranges = getattr(trajectory, "ranges", None)
    rg = None if ranges is None else np.asarray(ranges, dtype=np.float64)
    t = getattr(trajectory, "t", None)
    times = None if t is None else np.asarray(t, dtype=np.float64)
    ray_ids: tuple[int, ...] | None = None
    if rg is not None and rg.ndim == 3 and not overlay:
        try:
            ray_ids = sonar_indices(rg.shape[-1], sonars)
        except MbnInputError:
            if sonars is not None:
                raise
            ray_ids = None

    def default_title(i: int) -> str:
        p = pose[i]
        dist = float(np.hypot(np.diff(p[:, 0]), np.diff(p[:, 1])).sum())
        parts = [f"robot {i}: {dist:.1f} m"]
        if times is not None and times.size > 1:
            span = times[-1] - times[0] + (times[1] - times[0])
            parts.append(f"in {span:.0f} s")
        if st is not None:
            parts.append(f"{100 * st[i].mean():.0f} % stalled")
        return ", ".join(parts)

    suptitle = maze.name if title is None else title
    if overlay:
        fig = draw_maze(maze, legend=False, title=suptitle)
        ax = fig.axes[0]
        for j, i in enumerate(idx):
            draw_trajectory(
                maze,
                pose[i],
                ax,
                color=PATH_COLORS[j % len(PATH_COLORS)],
                footprints_every=0 if footprints_every is None else footprints_every,
                stalled=None if st is None else st[i],
                label=titles[j] if titles is not None else f"robot {i}",
            )
        handles = [h for h in ax.get_lines() if h.get_gid() == "path"]
        handles += maze_legend_handles(maze, junctions=True, starts=True, tiles=True)
        if st is not None and st[idx].any():
            handles.append(
                Line2D([], [], color=STALL_COLOR, marker="x", ls="", mew=1.6, label="stall")
            )
        legend_below(ax, handles)
    else:
        if ncols is None:
            cols = len(idx) if len(idx) <= 3 else (2 if len(idx) == 4 else 3)
        else:
            cols = max(1, int(ncols))
        rows = math.ceil(len(idx) / cols)
        pw, ph = maze_figsize(maze, longest=4.2, extra_h=0.5)
        fig = new_figure((pw * cols, ph * rows + 0.6))
        # one maze in every panel: shared axes, tick labels and axis labels on the outer ones
        axes = fig.subplots(rows, cols, squeeze=False, sharex=True, sharey=True)
        for j, i in enumerate(idx):
            ax = axes[j // cols][j % cols]
            draw_maze(
                maze,
                ax,
                legend=False,
                title=titles[j] if titles is not None else default_title(i),
            )
            ax.title.set_fontsize(9)
            draw_trajectory(
                maze,
                pose[i],
                ax,
                footprints_every=footprints_every,
                stalled=None if st is None else st[i],
                sonar_at=[pose.shape[1] - 1] if ray_ids is not None else (),
                ranges=None if rg is None else rg[i],
                sonars=ray_ids,
            )
        for j in range(len(idx), rows * cols):
            axes[j // cols][j % cols].set_visible(False)
        for j in range(len(idx)):
            ax = axes[j // cols][j % cols]
            if j + cols < len(idx):  # a panel below it: no x labels
                ax.tick_params(labelbottom=False)
                ax.set_xlabel("")
            if j % cols:
                ax.tick_params(labelleft=False)
                ax.set_ylabel("")
        handles = maze_legend_handles(maze, junctions=True, starts=True, tiles=True)
        handles.append(Line2D([], [], color=PATH_COLORS[0], lw=1.6, label="path"))
        if st is not None and st[idx].any():
            handles.append(
                Line2D([], [], color=STALL_COLOR, marker="x", ls="", mew=1.6, label="stall")
            )
        if ray_ids is not None:
            handles.append(Line2D([], [], color=RAY_COLOR, lw=0.9, label="sonar rays (end)"))
        legend_below(fig, handles)
        fig.suptitle(suptitle)
    if path is not None:
        save_png(fig, path)
    return fig


class EpisodeView:
    """A maze with one robot drawn on it, updated in place: the frames of an animation.

    :meth:`update` moves the body octagon, its heading tick and trail, redraws the sonar rays and
    the camera's field of view (coloured by what the camera sees: grey nothing, orange a
    one-colour tile, magenta a two-colour tile), and writes a status line (time, camera, tile in
    force, stall) as the axes title; :meth:`rgb` renders the frame to an ``(H, W, 3)`` uint8
    array. The maze is rendered once and kept as a background; a frame only draws what moves.
    ``figure`` is an ordinary Figure: saving it shows the last update.
    """

    def __init__(
        self,
        maze: Maze,
        *,
        width: float = 6.0,
        dpi: float = 80.0,
        title: str | None = None,
        color: str = PATH_COLORS[0],
        camera_fov_deg: float | None = None,
        camera_range: float = 3.0,
    ) -> None:
        """Draw ``maze`` (a figure ``width`` inches wide at ``dpi``) with ``title`` above it
        (default the maze's name); ``camera_fov_deg`` draws the camera's field of view
        (``camera_range`` metres) when given."""
        self.maze = maze
        w, h = maze_figsize(maze, longest=width, extra_h=0.7)
        self.figure = new_figure((w, h), dpi=dpi)
        self.ax = self.figure.add_subplot()
        draw_maze(maze, self.ax, legend=False, title="")
        self.figure.suptitle(maze.name if title is None else title, fontsize=11)
        self.color = color
        ax = self.ax
        self.fov_deg = camera_fov_deg
        # below the walls: the wedge shows where the camera looks, in free space only
        self.fov = Wedge((0.0, 0.0), camera_range, 0.0, 0.0, alpha=0.22, lw=0, zorder=1.5)
        self.fov.set_visible(False)
        ax.add_patch(self.fov)
        self.trail = Line2D([], [], color=color, lw=1.4, alpha=0.85, zorder=5, gid="trail")
        ax.add_line(self.trail)
        self.rays = LineCollection([], colors=RAY_COLOR, linewidths=0.9, zorder=5.5, gid="rays")
        self.misses = LineCollection(
            [], colors=RAY_COLOR, linewidths=0.8, linestyles=":", alpha=0.7, zorder=5.5
        )
        ax.add_collection(self.rays)
        ax.add_collection(self.misses)
        self.echoes = Line2D([], [], ls="", marker=".", color=RAY_COLOR, ms=4, zorder=5.5)
        ax.add_line(self.echoes)
        self.body = Polygon(
            np.zeros((8, 2)),
            closed=True,
            facecolor=color,
            alpha=0.6,
            edgecolor=color,
            linewidth=1.2,
            zorder=6,
            gid="body",
        )
        ax.add_patch(self.body)
        self.heading = Line2D([], [], color="white", lw=1.5, zorder=6.5, gid="heading")
        ax.add_line(self.heading)
        self.stall_mark = Line2D(
            [], [], ls="", marker="x", color=STALL_COLOR, ms=9, mew=2.2, zorder=7
        )
        ax.add_line(self.stall_mark)
        ax.set_title(" ", fontsize=9, family="monospace")
        self._walls = [a for a in ax.patches if a.get_gid() in ("wall", "frame")]
        self._background: Any = None
        self._limits: tuple[tuple[float, float], tuple[float, float]] | None = None

    @property
    def artists(self) -> list[Artist]:
        """The artists :meth:`update` changes, in drawing order."""
        return [
            self.fov,
            self.trail,
            self.rays,
            self.misses,
            self.echoes,
            self.body,
            self.heading,
            self.stall_mark,
            self.ax.title,
        ]

    def update(
        self,
        pose: ArrayLike,
        *,
        trail: ArrayLike | None = None,
        ranges: ArrayLike | None = None,
        sonars: Sequence[int] | None = None,
        camera: int | None = None,
        tile: int | None = None,
        t: float | None = None,
        stalled: bool = False,
    ) -> None:
        """Show the robot at ``pose (3,)``, with the ``trail (m, 3)`` behind it, its sonar
        ``ranges (k,)`` (Stage indices ``sonars``, see :func:`draw_trajectory`), the camera's
        reading (colours of the nearest tile in view: 0, 1, 2), the tile in force, the time (s)
        and whether it is stalled."""
        p = poses_array(np.asarray(pose, dtype=np.float64).reshape(1, 3), "pose")[0]
        self.body.set_xy(_body(p[None])[0])
        nose = float(BODY[:, 0].max())
        self.heading.set_data(
            [p[0], p[0] + nose * math.cos(p[2])], [p[1], p[1] + nose * math.sin(p[2])]
        )
        if trail is not None:
            tr = np.asarray(trail, dtype=np.float64).reshape(-1, 3)
            self.trail.set_data(tr[:, 0], tr[:, 1])
        else:
            self.trail.set_data([], [])
        if ranges is not None:
            r = np.asarray(ranges, dtype=np.float64).reshape(-1)
            segs, hit = _ray_segments(p, r, sonar_indices(r.size, sonars))
            self.rays.set_segments(list(segs[hit]))
            self.misses.set_segments(list(segs[~hit]))
            self.echoes.set_data(segs[hit, 1, 0], segs[hit, 1, 1])
        else:
            self.rays.set_segments([])
            self.misses.set_segments([])
            self.echoes.set_data([], [])
        if self.fov_deg is not None:
            from mbn.world.engine import CAMERA_POSITION

            cx = p[0] + math.cos(p[2]) * CAMERA_POSITION[0]
            cy = p[1] + math.sin(p[2]) * CAMERA_POSITION[0]
            deg = math.degrees(p[2])
            self.fov.set_center((cx, cy))
            self.fov.set_theta1(deg - self.fov_deg / 2)
            self.fov.set_theta2(deg + self.fov_deg / 2)
            self.fov.set_facecolor(_CAMERA_FOV_COLORS.get(int(camera or 0), "#9aa0a6"))
            self.fov.set_visible(True)
        if stalled:
            self.stall_mark.set_data([p[0]], [p[1]])
        else:
            self.stall_mark.set_data([], [])
        parts = []
        if t is not None:
            parts.append(f"t = {t:6.1f} s")
        if camera is not None:
            parts.append(f"camera: {_TILE_WORDS.get(int(camera), str(camera)):8s}")
        if tile is not None:
            parts.append(f"tile in force: {_TILE_WORDS.get(int(tile), str(tile)):8s}")
        parts.append("STALLED" if stalled else "       ")
        self.ax.set_title("  ".join(parts), fontsize=9, family="monospace")
        _limits_with(self.ax, self.maze, p[None])

    def rgb(self) -> np.ndarray:
        """The current frame as an ``(H, W, 3)`` uint8 array.

        The first frame fixes the layout and renders the maze alone as a background; later
        frames restore it and draw only the robot's artists over it (the walls again over the
        camera's wedge). The background is rendered again when the axes limits change, as they
        can in an open maze."""
        canvas: Any = self.figure.canvas
        limits = (self.ax.get_xlim(), self.ax.get_ylim())
        if self._background is None or limits != self._limits:
            if self._background is None:
                canvas.draw()  # lay out with every artist in place, then keep that layout
                self.figure.set_layout_engine("none")
            title_at = self.ax.title.get_position()
            shown = [a.get_visible() for a in self.artists]
            for a in self.artists:
                a.set_visible(False)
            canvas.draw()
            self._background = canvas.copy_from_bbox(self.figure.bbox)
            for a, v in zip(self.artists, shown, strict=True):
                a.set_visible(v)
            self.ax.title.set_position(title_at)  # a hidden title is placed off the axes
            self._limits = limits
        else:
            canvas.restore_region(self._background)
        if self.fov.get_visible():
            self.ax.draw_artist(self.fov)
            for patch in self._walls:
                self.ax.draw_artist(patch)
        for a in self.artists[1:]:
            self.ax.draw_artist(a)
        buf = np.asarray(canvas.buffer_rgba())
        return np.array(buf[..., :3], dtype=np.uint8)
