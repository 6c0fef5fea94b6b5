"""Animated GIFs of robot episodes (frames by :class:`~mbn.viz.episodes.EpisodeView`, Pillow).

* :func:`animate_episode` — the robot's footprint moving with its trail, the sonar rays, the
  camera's field of view and a status line, written as a GIF with one shared palette.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import ArrayLike

from mbn.errors import MbnInputError
from mbn.io import atomic_open
from mbn.viz.episodes import EpisodeView, poses_array, sonar_indices
from mbn.world.mazes.model import Maze

__all__ = ["animate_episode"]

_GIF_MAX_FRAMES = 150


def _gif_palette(samples: list[np.ndarray]) -> Any:
    """One palette (a ``P`` image of 255 colours) for every frame of a GIF, from a few frames:
    one palette keeps colours steady from frame to frame and lets Pillow store only what changed.
    """
    from PIL import Image

    montage = Image.fromarray(np.concatenate(samples, axis=0))
    return montage.quantize(colors=255, method=Image.Quantize.MEDIANCUT)


def animate_episode(
    maze: Maze,
    poses: ArrayLike,
    path: str | os.PathLike[str],
    *,
    ranges: ArrayLike | None = None,
    sonars: Sequence[int] | None = None,
    camera: ArrayLike | None = None,
    tile: ArrayLike | None = None,
    stalled: ArrayLike | None = None,
    t: ArrayLike | None = None,
    dt: float = 0.1,
    fps: float = 10.0,
    every: int = 1,
    max_frames: int = _GIF_MAX_FRAMES,
    dpi: float = 100.0,
    width: float = 6.0,
    title: str | None = None,
    camera_fov_deg: float = 60.0,
    camera_range: float = 3.0,
) -> Figure:
    """Write an animated GIF of one episode: the robot's footprint moving with its trail, the sonar
    rays, the camera's field of view and a status line (time, camera reading, tile in force).

    Frames show samples ``0, every, 2 every, ...``; when that would exceed ``max_frames`` (150 by
    default), ``every`` is raised to ``ceil(n / max_frames)`` so the GIF stays modest: the GIF
    then has ``ceil(n / every)`` frames. Each frame lasts ``1 / fps`` seconds. Frames are rendered
    with the Agg canvas (:class:`EpisodeView`) and written by Pillow with one shared 255-colour
    palette, to a temporary file beside ``path`` that is then renamed over it.

    Args:
        maze: the maze.
        poses: ``(n, 3)`` poses, e.g. ``trajectory.pose[b]``.
        path: the GIF to write.
        ranges: ``(n, k)`` sonar readings to draw as rays (``sonars``: their Stage indices, see
            :func:`~mbn.viz.episodes.draw_trajectory`).
        camera: ``(n,)`` camera readings (colours of the nearest tile in view: 0, 1, 2); also
            turns on the field-of-view wedge (``camera_fov_deg`` wide, ``camera_range`` long).
        tile: ``(n,)`` tile in force (0, 1, 2).
        stalled: ``(n,)`` bool.
        t: ``(n,)`` sample times (s); default ``i * dt``.
        dt: seconds between samples when ``t`` is not given.
        fps: frames per second of the GIF.
        every: draw every that many samples (raised automatically, see above).
        max_frames: the most frames written.
        dpi, width: frame resolution and width (inches); 6 in at 100 dpi gives frames 600 px
            wide.
        title: the title above the maze (default the maze's name).

    Returns:
        The Figure (showing the last frame).
    """
    from PIL import Image

    p = poses_array(poses)
    n = p.shape[0]
    if isinstance(every, bool) or not (isinstance(every, int) and every >= 1):
        raise MbnInputError(f"every must be an integer >= 1, got {every!r}")
    if isinstance(max_frames, bool) or not (isinstance(max_frames, int) and max_frames >= 1):
        raise MbnInputError(f"max_frames must be an integer >= 1, got {max_frames!r}")
    if not (fps > 0 and math.isfinite(fps)):
        raise MbnInputError(f"fps must be > 0, got {fps!r}")
    target = Path(path)
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.is_dir():
        raise MbnInputError(f"{target}: folder {folder} does not exist")

    def per_sample(a: ArrayLike | None, name: str, dtype: Any) -> np.ndarray | None:
        if a is None:
            return None
        arr = np.asarray(a, dtype=dtype)
        if arr.shape[:1] != (n,):
            raise MbnInputError(f"{name} must have {n} samples (first axis), got {arr.shape}")
        return arr

    rg = per_sample(ranges, "ranges", np.float64)
    cam = per_sample(camera, "camera", np.int64)
    tl = per_sample(tile, "tile", np.int64)
    st = per_sample(stalled, "stalled", bool)
    times = per_sample(t, "t", np.float64)
    if times is None:
        times = np.arange(n) * float(dt)
    if rg is not None and rg.ndim != 2:
        raise MbnInputError(f"ranges must have shape ({n}, k), got {rg.shape}")
    ids = None if rg is None else sonar_indices(rg.shape[1], sonars)
    every = max(every, math.ceil(n / max_frames))
    frames_at = np.arange(0, n, every)
    view = EpisodeView(
        maze,
        width=width,
        dpi=dpi,
        title=title,
        camera_fov_deg=camera_fov_deg if cam is not None else None,
        camera_range=camera_range,
    )

    def render(i: int) -> np.ndarray:
        view.update(
            p[i],
            trail=p[: i + 1],
            ranges=None if rg is None else rg[i],
            sonars=ids,
            camera=None if cam is None else int(cam[i]),
            tile=None if tl is None else int(tl[i]),
            t=float(times[i]),
            stalled=bool(st[i]) if st is not None else False,
        )
        return view.rgb()

    picks = sorted({int(frames_at[0]), int(frames_at[len(frames_at) // 2]), int(frames_at[-1])})
    palette = _gif_palette([render(i) for i in picks])
    images = [
        Image.fromarray(render(int(i))).quantize(palette=palette, dither=Image.Dither.NONE)
        for i in frames_at
    ]
    with atomic_open(target, "wb") as handle:
        images[0].save(
            handle,
            format="GIF",
            save_all=True,
            append_images=images[1:],
            duration=max(1, round(1000 / fps)),
            loop=0,
        )
    return view.figure
