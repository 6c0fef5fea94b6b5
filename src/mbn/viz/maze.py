"""Pictures of mazes: walls, floor tiles, decision cells and start poses (matplotlib, Agg).

* :func:`draw_maze` / :func:`save_maze_png` — a maze on new or given axes, or as a PNG;
* the helpers the other pictures of a maze share: :func:`maze_figsize` (a figure sized to the
  maze), :func:`maze_legend_handles` and :func:`legend_below` (the legend under a picture),
  :func:`root_figure`.

Figures are made and saved by :mod:`mbn.viz.style`. Coordinates are the world's: metres, x east,
y north, equal aspect. Colours: walls dark grey, free space white, decision cells of grid mazes
pale blue, one-colour tiles orange, two-colour tiles blue (blob 0, the half to the right of the
tile's heading) and magenta (blob 1), three-colour tiles green, yellow and teal (blobs 0, 1, 2),
tiles of four, five and six colours in palettes of their own (:data:`TILE_PALETTES`) hatched
in white, one diagonal, the other diagonal and crossed (:data:`TILE_HATCHES`), start poses
green arrows numbered 1, 2, ... in the order of ``maze.starts`` (as ``mbn evaluate`` and the
episode panels' titles count them).
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import FancyArrow, Patch, Polygon, Rectangle

from mbn.viz.style import new_figure, save_png
from mbn.world.mazes.model import DEFAULT_CELL, Maze

__all__ = [
    "DECISION_COLOR",
    "START_COLOR",
    "TILE1_COLOR",
    "TILE2_COLORS",
    "TILE3_COLORS",
    "TILE4_COLORS",
    "TILE5_COLORS",
    "TILE6_COLORS",
    "TILE_HATCHES",
    "TILE_PALETTES",
    "WALL_COLOR",
    "draw_maze",
    "legend_below",
    "maze_figsize",
    "maze_legend_handles",
    "root_figure",
    "save_maze_png",
]

WALL_COLOR = "#3a3d42"
DECISION_COLOR = "#dfe8f5"
TILE1_COLOR = "#f28e2b"
TILE2_COLORS = ("#2f6db5", "#c936c0")
TILE3_COLORS = ("#2ca02c", "#e6b800", "#17becf")
TILE4_COLORS = ("#8c564b", "#e377c2", "#9467bd", "#bcbd22")
TILE5_COLORS = ("#d62728", "#1f77b4", "#ff9896", "#98df8a", "#c5b0d5")
TILE6_COLORS = ("#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173", "#5254a3")
#: The colours of each tile kind's parts (blob 0 first), by the kind's colours.
TILE_PALETTES: dict[int, tuple[str, ...]] = {
    1: (TILE1_COLOR,),
    2: TILE2_COLORS,
    3: TILE3_COLORS,
    4: TILE4_COLORS,
    5: TILE5_COLORS,
    6: TILE6_COLORS,
}
#: White hatching over the tiles of four, five and six colours (the others: none).
TILE_HATCHES: dict[int, str] = {4: "//", 5: "\\\\", 6: "xx"}
_KIND_WORDS = {1: "one", 2: "two", 3: "three", 4: "four", 5: "five", 6: "six"}
START_COLOR = "#1e8a3c"


def root_figure(ax: Axes) -> Figure:
    """The top-level Figure holding ``ax`` (also when ``ax`` lives in a SubFigure)."""
    fig: Any = ax.figure
    while not isinstance(fig, Figure):
        fig = fig.figure
    return fig


def _extent(maze: Maze) -> tuple[float, float, float, float]:
    """The drawn area: ``bounds`` plus the frame (walled mazes) or a margin (open mazes)."""
    x0, x1, y0, y1 = maze.bounds
    pad = _frame_width(maze) if maze.outside_is_wall else 0.05 * max(x1 - x0, y1 - y0)
    return x0 - pad, x1 + pad, y0 - pad, y1 + pad


def _frame_width(maze: Maze) -> float:
    x0, x1, y0, y1 = maze.bounds
    return max(0.05, 0.012 * max(x1 - x0, y1 - y0))


def _scale(maze: Maze) -> float:
    """A length for markers: the grid cell, or the default corridor width."""
    return float(maze.cell) if maze.cell is not None else DEFAULT_CELL


def maze_figsize(maze: Maze, longest: float = 7.0, extra_h: float = 0.9) -> tuple[float, float]:
    """Figure size (inches) for one maze panel: the longer side ``longest`` inches."""
    x0, x1, y0, y1 = _extent(maze)
    w, h = x1 - x0, y1 - y0
    if w >= h:
        return longest, max(3.0, longest * h / w) + extra_h
    return max(3.5, longest * w / h) + 0.6, longest + extra_h


def maze_legend_handles(maze: Maze, *, junctions: bool, starts: bool, tiles: bool) -> list[Any]:
    handles: list[Any] = [Patch(facecolor=WALL_COLOR, label="wall")]
    if junctions and maze.grid is not None:
        handles.append(Patch(facecolor=DECISION_COLOR, edgecolor="#b9c6d8", label="decision cell"))
    kinds = {t.colors for t in maze.tiles} if tiles else set()
    if 1 in kinds:
        handles.append(Patch(facecolor=TILE1_COLOR, label="one-colour tile"))
    for n in sorted(kinds - {1}):  # adjacent swatches, one per part
        label = f"{_KIND_WORDS.get(n, str(n))}-colour tile"
        styles = [_tile_style(n, color) for color in TILE_PALETTES[n]]
        if n not in TILE_HATCHES:
            styles = [{"facecolor": style["facecolor"]} for style in styles]
        handles.append((Patch(**styles[0], label=label), *(Patch(**style) for style in styles[1:])))
    if starts and len(maze.starts):
        handles.append(
            Line2D([], [], color=START_COLOR, marker=">", ls="-", lw=1.5, ms=6, label="start")
        )
    return handles


def legend_below(target: Figure | Axes, handles: list[Any]) -> None:
    """A legend below the figure (or the axes) holding ``handles``; a tuple of patches is one
    entry drawn as adjacent swatches (a two-colour tile)."""
    from matplotlib.legend_handler import HandlerTuple

    labels = [(h[0] if isinstance(h, tuple) else h).get_label() for h in handles]
    kw: dict[str, Any] = {
        "handler_map": {tuple: HandlerTuple(ndivide=None, pad=0.0)},
        "frameon": False,
        "fontsize": 8,
        "ncol": len(handles) if len(handles) <= 8 else math.ceil(len(handles) / 2),
        "handlelength": 2.0,
        "columnspacing": 1.2,
    }
    if isinstance(target, Figure):
        target.legend(handles, labels, loc="outside lower center", **kw)
    else:
        target.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, -0.09), **kw)


#: Above this many rectangles of one layer, they are drawn as one raster image (an artist with
#: that layer's gid) of at most :data:`RASTER_PIXELS` pixels a side, filled with NumPy: time and
#: memory stay bounded by the picture, not the maze (a 1000 x 1000-cell maze draws in seconds).
#: Below it, one patch each.
MAX_PATCHES = 2000
#: The longer side of a layer's raster image, in pixels at most.
RASTER_PIXELS = 2048


def _raster_step(maze: Maze) -> float:
    """The pixel side of the raster images of ``maze``: a whole fraction of a grid's square cell
    (so that cell borders fall on pixel borders), else the longer side of the bounds over
    :data:`RASTER_PIXELS`."""
    x0, x1, y0, y1 = maze.bounds
    if maze.grid is not None and maze.cell is not None:
        per_cell = RASTER_PIXELS // max(np.shape(maze.grid))
        if per_cell >= 1:
            return float(maze.cell) / per_cell
    return max(x1 - x0, y1 - y0) / RASTER_PIXELS


def _add_raster(ax: Axes, maze: Maze, rects: np.ndarray, *, gid: str, **style: Any) -> None:
    """Rectangles ``(K, 4)`` (clipped to the bounds) as one RGBA image in ``style["facecolor"]``:
    every rectangle covers at least one pixel, so thin walls stay visible."""
    from matplotlib.colors import to_rgba

    x0, x1, y0, y1 = maze.bounds
    step = _raster_step(maze)
    nx = max(1, math.ceil((x1 - x0) / step - 1e-6))
    ny = max(1, math.ceil((y1 - y0) / step - 1e-6))
    r = np.clip(rects, [x0, x0, y0, y0], [x1, x1, y1, y1])
    i0 = np.clip(np.floor((r[:, 0] - x0) / step + 1e-6), 0, nx - 1).astype(np.int64)
    i1 = np.clip(np.ceil((r[:, 1] - x0) / step - 1e-6), i0 + 1, nx).astype(np.int64)
    j0 = np.clip(np.floor((r[:, 2] - y0) / step + 1e-6), 0, ny - 1).astype(np.int64)
    j1 = np.clip(np.ceil((r[:, 3] - y0) / step - 1e-6), j0 + 1, ny).astype(np.int64)
    cover = np.zeros((ny + 1, nx + 1), np.int32)
    np.add.at(cover, (j0, i0), 1)
    np.add.at(cover, (j0, i1), -1)
    np.add.at(cover, (j1, i0), -1)
    np.add.at(cover, (j1, i1), 1)
    inside = np.cumsum(np.cumsum(cover, 0), 1)[:ny, :nx] > 0  # row 0 south
    image = np.zeros((ny, nx, 4), np.uint8)
    image[inside] = np.round(np.array(to_rgba(style["facecolor"])) * 255).astype(np.uint8)
    ax.imshow(
        image,
        origin="lower",
        extent=(x0, x0 + nx * step, y0, y0 + ny * step),
        interpolation="nearest",
        zorder=style.get("zorder", 1),
        gid=gid,
    )


def _tile_parts(tiles: list[Any], n: int) -> np.ndarray:
    """The parts of ``tiles`` (all of ``n`` colours), ``(K, n, 4, 2)``: equal strips across the
    corridor (blob 0 first), each with the corners of :meth:`Tile.corners` (computed for all at
    once)."""
    if not tiles:
        return np.zeros((0, n, 4, 2))
    x, y, w, length, h = (
        np.array([getattr(t, k) for t in tiles]) for k in ("x", "y", "width", "length", "heading")
    )
    along = np.stack([np.cos(h), np.sin(h)], -1) * (length / 2)[:, None]
    across = np.stack([-np.sin(h), np.cos(h)], -1) * (w / 2)[:, None]
    centre = np.stack([x, y], -1)
    c = np.stack(
        [
            centre - along - across,
            centre + along - across,
            centre + along + across,
            centre - along + across,
        ],
        1,
    )
    f = (np.arange(n + 1) / n)[None, :, None]
    lo = c[:, None, 0] + (c[:, None, 3] - c[:, None, 0]) * f  # (K, n + 1, 2)
    hi = c[:, None, 1] + (c[:, None, 2] - c[:, None, 1]) * f
    return np.stack([lo[:, :-1], hi[:, :-1], hi[:, 1:], lo[:, 1:]], 2)


def _tile_style(n: int, color: str) -> dict[str, Any]:
    """The patch style of a part of a tile of ``n`` colours: its colour, and for four to six
    colours white hatching (the hatch takes the edge colour; no outline is drawn)."""
    hatch = TILE_HATCHES.get(n)
    if hatch is None:
        return {"facecolor": color, "edgecolor": "none"}
    return {"facecolor": color, "edgecolor": "white", "linewidth": 0.0, "hatch": hatch}


def _add_rectangles(ax: Axes, maze: Maze, rects: np.ndarray, *, gid: str, **style: Any) -> None:
    """Rectangles ``(K, 4)`` as ``(xmin, xmax, ymin, ymax)``: a patch each, or one raster image
    (its gid ``gid``, :func:`_add_raster`) when there are more than :data:`MAX_PATCHES`."""
    rects = np.asarray(rects, dtype=float).reshape(-1, 4)
    if len(rects) > MAX_PATCHES:
        _add_raster(ax, maze, rects, gid=gid, **style)
        return
    for xa, xb, ya, yb in rects.tolist():
        patch = Rectangle((xa, ya), xb - xa, yb - ya, gid=gid)
        patch.set(**style)
        ax.add_patch(patch)


def draw_maze(
    maze: Maze,
    ax: Axes | None = None,
    *,
    junctions: bool = True,
    starts: bool = True,
    tiles: bool = True,
    title: str | None = None,
    legend: bool | None = None,
) -> Figure:
    """Draw ``maze``: walls, free space, tiles, decision cells and start poses.

    Walls are dark grey rectangles (artists with gid ``"wall"``, one per row of ``maze.walls``, or
    above :data:`MAX_PATCHES` of them one raster image with that gid, as for decision cells);
    a maze whose outside is solid also gets a dark frame round its bounds (gid ``"frame"``). Tiles
    are drawn from :meth:`Tile.corners`: one-colour tiles orange (gid ``"tile1"``), two-colour
    tiles as two halves across the corridor (gid ``"tile2"``: blue is blob 0, magenta blob 1),
    three-colour tiles as three thirds (gid ``"tile3"``: green, yellow, teal), tiles of ``n`` =
    4, 5, 6 colours as ``n`` parts (gid ``"tile{n}"``, :data:`TILE_PALETTES`, hatched
    :data:`TILE_HATCHES`).
    Decision cells of grid mazes (:func:`mbn.world.junctions.decision_cells`) are shaded pale blue
    (gid ``"decision"``); start poses are green arrows (gid ``"start"``) labelled 1, 2, ... in
    the order of ``maze.starts``. Above :data:`MAX_PATCHES` of a kind, tiles are drawn as raster
    images of their parts' bounding boxes and start poses as one field of arrows, unnumbered.

    Args:
        maze: the maze.
        ax: axes to draw on; None makes a new figure sized to the maze.
        junctions, starts, tiles: whether to draw each of those layers.
        title: the axes title; None uses the maze's name, ``""`` none.
        legend: a legend below the axes; None means yes for a new figure, no on given axes.

    Returns:
        The Figure drawn on.
    """
    new = ax is None
    if ax is None:
        fig = new_figure(maze_figsize(maze))
        ax = fig.add_subplot()
    else:
        fig = root_figure(ax)
    _, x1, y0, y1 = maze.bounds
    ex0, ex1, ey0, ey1 = _extent(maze)
    ax.set_facecolor("white")
    if junctions and maze.grid is not None:
        from mbn.world.junctions import decision_cells

        dec = decision_cells(maze)
        xe, ye = maze.grid_edges()
        rows = dec.shape[0]
        r_idx, c_idx = np.nonzero(dec)
        south = rows - 1 - r_idx
        _add_rectangles(
            ax,
            maze,
            np.stack([xe[c_idx], xe[c_idx + 1], ye[south], ye[south + 1]], -1),
            facecolor=DECISION_COLOR,
            edgecolor="none",
            zorder=0.5,
            gid="decision",
        )
    if tiles:
        for n, colors in TILE_PALETTES.items():
            parts = _tile_parts([t for t in maze.tiles if t.colors == n], n)
            for i, color in enumerate(colors):  # equal parts across the corridor, blob 0 first
                if len(parts) > MAX_PATCHES:
                    x, y = parts[:, i, :, 0], parts[:, i, :, 1]
                    boxes = np.stack([x.min(1), x.max(1), y.min(1), y.max(1)], -1)
                    _add_raster(ax, maze, boxes, gid=f"tile{n}", facecolor=color, zorder=1)
                    continue
                style = _tile_style(n, color)
                for part in parts[:, i]:
                    ax.add_patch(Polygon(part, closed=True, zorder=1, gid=f"tile{n}", **style))
    _add_rectangles(
        ax,
        maze,
        maze.walls,
        facecolor=WALL_COLOR,
        edgecolor=WALL_COLOR,
        linewidth=0.4,
        zorder=2,
        gid="wall",
    )
    if maze.outside_is_wall:
        f = _frame_width(maze)
        for rect in (
            (ex0, ey0, ex1 - ex0, f),
            (ex0, y1, ex1 - ex0, f),
            (ex0, y0, f, y1 - y0),
            (x1, y0, f, y1 - y0),
        ):
            ax.add_patch(
                Rectangle(
                    rect[:2],
                    rect[2],
                    rect[3],
                    facecolor=WALL_COLOR,
                    edgecolor=WALL_COLOR,
                    linewidth=0.4,
                    zorder=2,
                    gid="frame",
                )
            )
    if starts and len(maze.starts) > MAX_PATCHES:  # one artist: arrows without numbers
        sx, sy, sth = np.asarray(maze.starts).T
        reach = 0.5 * _scale(maze)
        ax.quiver(
            sx - 0.5 * reach * np.cos(sth),
            sy - 0.5 * reach * np.sin(sth),
            reach * np.cos(sth),
            reach * np.sin(sth),
            angles="xy",
            scale_units="xy",
            scale=1.0,
            color=START_COLOR,
            zorder=4,
            gid="start",
        )
    elif starts and len(maze.starts):
        s = _scale(maze)
        length = 0.5 * s
        for k, (x, y, th) in enumerate(maze.starts):
            d = np.array([math.cos(th), math.sin(th)])
            tail = np.array([x, y]) - 0.5 * length * d
            ax.add_patch(
                FancyArrow(
                    tail[0],
                    tail[1],
                    length * d[0],
                    length * d[1],
                    width=0.06 * s,
                    head_width=0.24 * s,
                    head_length=0.2 * s,
                    length_includes_head=True,
                    facecolor=START_COLOR,
                    edgecolor="white",
                    linewidth=0.5,
                    zorder=4,
                    gid="start",
                )
            )
            label = np.array([x, y]) - (0.5 * length + 0.13 * s) * d
            ax.text(
                label[0],
                label[1],
                str(k + 1),
                color=START_COLOR,
                fontsize=8,
                fontweight="bold",
                ha="center",
                va="center",
                zorder=4,
                gid="start_label",
            )
    ax.set_xlim(ex0, ex1)
    ax.set_ylim(ey0, ey1)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.tick_params(labelsize=8)
    ax.set_title(maze.name if title is None else title)
    if legend if legend is not None else new:
        handles = maze_legend_handles(maze, junctions=junctions, starts=starts, tiles=tiles)
        legend_below(fig if new else ax, handles)
    return fig


def save_maze_png(
    maze: Maze, path: str | os.PathLike[str], *, dpi: float | None = None, **kw: Any
) -> Figure:
    """Draw ``maze`` (:func:`draw_maze`, keyword arguments passed on) and write it as a PNG
    (atomically) at ``dpi`` (default :data:`mbn.viz.style.DPI`)."""
    fig = draw_maze(maze, **kw)
    save_png(fig, path, dpi)
    return fig
