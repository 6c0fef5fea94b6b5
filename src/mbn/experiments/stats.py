"""Statistics of pass/fail counts shared by the pipeline's checks and the sweep's report."""

from __future__ import annotations

import math

__all__ = ["Z95", "wilson_interval"]

#: The normal quantile of a two-sided 95 % interval.
Z95 = 1.959963984540054


def wilson_interval(successes: int, trials: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of ``successes`` in ``trials`` (``(nan, nan)`` without
    trials). It holds the observed rate: at 0 and at ``trials`` successes one end is that rate
    exactly (in floats the formula's end can miss it by a rounding error)."""
    if trials <= 0:
        return math.nan, math.nan
    if not 0 <= successes <= trials:
        raise ValueError(f"successes {successes} not in [0, {trials}]")
    n, p = float(trials), successes / trials
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return min(p, max(0.0, centre - half)), max(p, min(1.0, centre + half))
