"""Start poses: the one jitter of every jittered start (training crossroads and test trials).

A jittered start moves a start mark across its heading (lateral), along it, and turns it, each by
a uniform amount up to the half-ranges of :data:`JITTER`, drawn by a NumPy generator seeded at
this edge (the seed is recorded in the results).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np

__all__ = ["JITTER", "Jitter", "jittered_starts", "mark_starts"]


class Jitter(NamedTuple):
    """Half-ranges of a jittered start."""

    lateral: float  # m, across the heading
    along: float  # m, along the heading
    heading_deg: float  # degrees


#: The jitter of the project (not in the paper, which starts from 10 fixed marks; the tests add
#: jittered starts so that a controller cannot pass by one exact start: docs/reproduce.md).
JITTER = Jitter(lateral=0.15, along=0.3, heading_deg=10.0)


def jittered_starts(
    base: np.ndarray, variants: int, jitter: tuple[float, float, float], seed: int
) -> np.ndarray:
    """``variants`` copies of the start poses ``base (S, 3)`` (axis-aligned headings), stacked
    variant-major: the poses themselves, then ``variants - 1`` jittered copies, each pose moved
    across its heading by up to ``jitter[0]`` m, along it by up to ``jitter[1]`` m and turned by
    up to ``jitter[2]`` degrees (uniform; a NumPy generator seeded by ``seed``, at this edge)."""
    rng = np.random.default_rng(seed)
    ahead = np.stack([np.round(np.cos(base[:, 2])), np.round(np.sin(base[:, 2]))], -1)
    right = np.stack([ahead[:, 1], -ahead[:, 0]], -1)
    starts = [base]
    lat, along, head = jitter
    for _ in range(variants - 1):
        j = np.zeros_like(base)
        u = rng.uniform(-lat, lat, len(base))
        v = rng.uniform(-along, along, len(base))
        j[:, :2] = u[:, None] * right + v[:, None] * ahead
        j[:, 2] = np.deg2rad(rng.uniform(-head, head, len(base)))
        starts.append(base + j)
    return np.concatenate(starts)


def mark_starts(
    marks: Iterable[tuple[float, float, float]] | np.ndarray,
    repeats: int,
    jitter: tuple[float, float, float],
    seed: int,
    exact_first: bool = True,
) -> np.ndarray:
    """Start poses ``(marks * repeats, 3)``: for each start mark, the mark itself and then
    ``repeats - 1`` jittered copies (``repeats`` jittered copies when ``exact_first`` is False),
    mark-major order; ``jitter`` as :data:`JITTER` (lateral m, along m, heading degrees)."""
    rng = np.random.default_rng(seed)
    lat, along, head = jitter
    out = []
    for x, y, th in marks:
        if exact_first:
            out.append((x, y, th))
        for _ in range(repeats - int(exact_first)):
            a = rng.uniform(-along, along)
            b = rng.uniform(-lat, lat)
            h = math.radians(rng.uniform(-head, head))
            out.append(
                (
                    x + a * math.cos(th) - b * math.sin(th),
                    y + a * math.sin(th) + b * math.cos(th),
                    th + h,
                )
            )
    return np.array(out, dtype=float)
