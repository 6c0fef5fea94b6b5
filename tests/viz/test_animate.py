"""Animated GIFs of episodes: the frames, their timing and the files."""

from __future__ import annotations

import math

import numpy as np
import pytest
from matplotlib.figure import Figure
from PIL import Image

from mbn.errors import MbnInputError
from mbn.viz.animate import animate_episode


def test_animate_episode_writes_a_gif_with_the_expected_frames(tee, tmp_path):
    n = 30
    poses = np.stack(
        [np.full(n, 3.0), np.linspace(1.8, 4.0, n), np.linspace(math.pi / 2, 2.0, n)], -1
    )
    ranges = np.tile(np.linspace(0.3, 5.0, 16), (n, 1))
    camera = (np.arange(n) // 10) % 3
    tile = np.where(np.arange(n) > 15, 1, 0)
    out = tmp_path / "episode.gif"
    fig = animate_episode(
        tee, poses, out, ranges=ranges, camera=camera, tile=tile, stalled=np.arange(n) == 5
    )
    assert isinstance(fig, Figure)
    assert out.stat().st_size > 20_000
    with Image.open(out) as im:
        assert im.format == "GIF"
        assert im.n_frames == n
        assert im.info["duration"] == 100
    # subsampled to at most max_frames: every = ceil(31 / 10) = 4, so ceil(31 / 4) = 8 frames
    poses31 = np.concatenate([poses, poses[-1:]])
    animate_episode(tee, poses31, out, max_frames=10, fps=5)
    with Image.open(out) as im:
        assert im.n_frames == 8
        assert im.info["duration"] == 200
    animate_episode(tee, poses, out, every=7)
    with Image.open(out) as im:
        assert im.n_frames == 5
    assert not list(tmp_path.glob(".*"))
    with pytest.raises(MbnInputError, match="every"):
        animate_episode(tee, poses, out, every=0)
    with pytest.raises(MbnInputError, match="samples"):
        animate_episode(tee, poses, out, camera=np.zeros(n + 1))
