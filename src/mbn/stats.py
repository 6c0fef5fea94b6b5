"""Statistics shared by the pipeline's checks and the reports: pass/fail counts (the Wilson
interval), and runs compared by the evaluations they needed to succeed, unsuccessful runs
censored at the budget (quantiles, the fraction solved against evaluations, the ratio of
medians with a bootstrap interval, the Mann–Whitney U test and the Vargha–Delaney A12), the
statistics of runs as rliable reports them (the interquartile mean and the probability of
improvement, each with a bootstrap interval; Agarwal et al., NeurIPS 2021), Holm's correction
across the comparisons of one table, and a split's performance profile.

Where SciPy computes the same thing it does (``scipy.stats.binomtest(...).proportion_ci``,
``mannwhitneyu``, ``bootstrap``, ``trim_mean``); ``tests/experiments/test_stats.py`` checks its
figures against the formulas written out. A base module (NumPy and SciPy only): the
experiments, their reports and the pictures (:mod:`mbn.viz`) all read it."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = [
    "Z95",
    "censored_quantiles",
    "describe",
    "forward_transfer",
    "holm",
    "iqm",
    "iqm_interval",
    "mann_whitney",
    "median_ratio",
    "paired_difference",
    "performance_profile",
    "probability_of_improvement",
    "solved_curve",
    "wilson_interval",
]

#: The normal quantile of a two-sided 95 % interval.
Z95 = 1.959963984540054


def describe(values: Sequence[float]) -> dict[str, float]:
    """Median, quartiles, min and max of ``values`` (NaN for an empty list)."""
    a = np.asarray(values, dtype=float)
    if a.size == 0:
        return dict.fromkeys(("median", "q1", "q3", "min", "max"), math.nan)
    q1, med, q3 = np.percentile(a, [25, 50, 75])
    return {
        "median": float(med),
        "q1": float(q1),
        "q3": float(q3),
        "min": float(a.min()),
        "max": float(a.max()),
    }


def wilson_interval(successes: int, trials: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of ``successes`` in ``trials`` at the two-sided level of the
    normal quantile ``z`` (``(nan, nan)`` without trials): SciPy's
    ``binomtest(successes, trials).proportion_ci(method="wilson")``. It holds the observed
    rate: at 0 and at ``trials`` successes one end is that rate exactly."""
    if trials <= 0:
        return math.nan, math.nan
    if not 0 <= successes <= trials:
        raise ValueError(f"successes {successes} not in [0, {trials}]")
    from scipy.stats import binomtest

    level = math.erf(z / math.sqrt(2))
    ci = binomtest(int(successes), int(trials)).proportion_ci(
        confidence_level=level, method="wilson"
    )
    p = successes / trials
    return min(p, float(ci.low)), max(p, float(ci.high))


# --- runs compared: evaluations to success, censored at the budget -------------------------


def _finite_or_censored(times: Sequence[float | None], budget: float) -> np.ndarray:
    """Hitting times with the unsuccessful runs (``None``) at the budget (right-censored)."""
    out = np.asarray([budget if t is None else float(t) for t in times], dtype=float)
    if np.any(out < 0) or np.any(out > budget):
        raise ValueError(f"a hitting time outside [0, {budget}]")
    return out


def _times_or_inf(times: Sequence[float | None], budget: float | None = None) -> np.ndarray:
    """Hitting times with the unsuccessful runs (``None``) at infinity: they need more
    evaluations than any run solved, one solved at the budget included. With ``budget``, a
    time outside [0, budget] raises."""
    out = np.asarray([math.inf if t is None else float(t) for t in times], dtype=float)
    solved = out[np.isfinite(out)]
    if budget is not None and (np.any(solved < 0) or np.any(solved > budget)):
        raise ValueError(f"a hitting time outside [0, {budget}]")
    return out


def _censored_order(t: np.ndarray, solved: np.ndarray) -> np.ndarray:
    """The order of runs by evaluations to success, a censored run after a run solved with as
    many (one solved at the last check, at the budget, needed fewer than one never solved)."""
    return np.lexsort((~solved, t))


def censored_quantiles(
    times: Sequence[float | None], budget: float
) -> dict[str, float | bool | None]:
    """Median and quartiles of evaluations to success over runs, an unsuccessful run (``None``)
    counted at ``budget`` (it would need at least that many). A quantile that falls on a
    censored run is not a number of evaluations but a lower bound: it is given as ``None``, and
    ``median_censored`` says so of the median ("> budget")."""
    t = _finite_or_censored(times, budget)
    if t.size == 0:
        return {"median": None, "q1": None, "q3": None, "median_censored": False}
    solved = np.asarray([x is not None for x in times])
    out: dict[str, float | bool | None] = {}
    order = _censored_order(t, solved)
    ts, ok = t[order], solved[order]
    for name, q in (("q1", 0.25), ("median", 0.5), ("q3", 0.75)):
        # type-7 quantile; it is a number of evaluations only if both order statistics it
        # interpolates between are solved runs
        h = (t.size - 1) * q
        lo, hi = math.floor(h), math.ceil(h)
        if ok[lo] and ok[hi]:
            out[name] = float(ts[lo] + (h - lo) * (ts[hi] - ts[lo]))
        else:
            out[name] = None
    out["median_censored"] = out["median"] is None
    return out


def solved_curve(
    times: Sequence[float | None], budget: float, points: int = 101
) -> tuple[np.ndarray, np.ndarray]:
    """The fraction of runs solved within ``e`` evaluations, for ``e`` from 0 to ``budget``
    (``points`` values): one minus a survival curve (no run leaves before the budget, so the
    empirical fraction is exact)."""
    grid = np.linspace(0.0, float(budget), points)
    hit = _times_or_inf(times)
    if hit.size == 0:
        return grid, np.full_like(grid, math.nan)
    return grid, (hit[None, :] <= grid[:, None]).mean(axis=1)


def _median_or_inf(t: np.ndarray, solved: np.ndarray) -> float:
    """Median of censored times: ``inf`` when it falls on a censored run."""
    order = _censored_order(t, solved)
    ts, ok = t[order], solved[order]
    h = (t.size - 1) * 0.5
    lo, hi = math.floor(h), math.ceil(h)
    if not (ok[lo] and ok[hi]):
        return math.inf
    return float(ts[lo] + (h - lo) * (ts[hi] - ts[lo]))


def median_ratio(
    a: Sequence[float | None],
    b: Sequence[float | None],
    budget: float,
    *,
    seed: int = 0,
    resamples: int = 10_000,
    level: float = 0.95,
) -> dict[str, float | bool | None]:
    """The ratio median(a) / median(b) of evaluations to success (unsuccessful runs censored
    at ``budget``) with a percentile bootstrap interval: each resample draws ``len(a)`` runs of
    ``a`` and ``len(b)`` of ``b`` with replacement (``seed``: NumPy's generator). A median that
    falls on a censored run is infinite, so the ratio (or an end of the interval) can be ``0``
    or unbounded: an unbounded ratio is ``None`` with ``ratio_unbounded``, an unbounded end
    ``None``; the ratio is ``None`` too where both medians are censored (it cannot be told).
    The interval's ends are order statistics of the resampled ratios (resamples with both
    medians censored left out, their share ``undefined_resamples``)."""
    ta, tb = _finite_or_censored(a, budget), _finite_or_censored(b, budget)
    if ta.size == 0 or tb.size == 0:
        return {"ratio": None, "low": None, "high": None}
    sa = np.asarray([x is not None for x in a])
    sb = np.asarray([x is not None for x in b])

    def ratio(ma: float, mb: float) -> float:
        if math.isinf(ma) and math.isinf(mb):
            return math.nan
        if math.isinf(mb):
            return 0.0
        if mb == 0:
            return math.inf if ma > 0 else 1.0
        return ma / mb

    point = ratio(_median_or_inf(ta, sa), _median_or_inf(tb, sb))
    rng = np.random.default_rng(seed)
    ia = rng.integers(0, ta.size, size=(resamples, ta.size))
    ib = rng.integers(0, tb.size, size=(resamples, tb.size))
    boots = np.asarray(
        [
            ratio(_median_or_inf(ta[i], sa[i]), _median_or_inf(tb[j], sb[j]))
            for i, j in zip(ia, ib, strict=True)
        ]
    )
    tail = (1 - level) / 2
    # a resample whose two medians are both censored has no ratio: it is left out, and the
    # share of those is recorded
    valid = boots[~np.isnan(boots)]

    def end(q: float) -> float | None:
        # an order statistic (no interpolation: an end may be infinite); JSON has no
        # infinity, so an unbounded end is ``None``
        if not valid.size:
            return None
        v = float(np.quantile(valid, q, method="inverted_cdf"))
        return None if math.isinf(v) else v

    return {
        "ratio": None if math.isnan(point) or math.isinf(point) else float(point),
        "ratio_unbounded": bool(math.isinf(point)),
        "low": end(tail),
        "high": end(1 - tail),
        "undefined_resamples": float(np.isnan(boots).mean()),
    }


def mann_whitney(
    a: Sequence[float | None], b: Sequence[float | None], budget: float
) -> dict[str, float | None]:
    """The Mann–Whitney U test of evaluations to success, ``a`` against ``b`` (unsuccessful runs
    tied with each other above every solved run, a run solved at ``budget`` included; ranks
    averaged over ties): ``U`` of ``a``, the two-sided p-value of the normal approximation with
    the tie correction and a continuity correction of 0.5 (SciPy's ``mannwhitneyu(...,
    method="asymptotic")``; 1 where every run ties), its signed normal deviate ``z``, and the
    Vargha–Delaney effect size ``A12`` = P(a > b) + P(a = b)/2: the chance that a run of ``a``
    needs more evaluations than one of ``b`` (0.5: no difference; below 0.5, ``a`` is faster).
    """
    from scipy.stats import mannwhitneyu, norm

    ta, tb = _times_or_inf(a, budget), _times_or_inf(b, budget)
    m, n = ta.size, tb.size
    if m == 0 or n == 0:
        return {"U": None, "p": None, "A12": None, "z": None}
    pooled = np.concatenate([ta, tb])
    if np.all(pooled == pooled[0]):  # every run tied: no evidence either way
        return {"U": m * n / 2, "p": 1.0, "A12": 0.5, "z": 0.0}
    # infinities (unsolved runs) rank above every number and tie with each other
    result = mannwhitneyu(ta, tb, alternative="two-sided", method="asymptotic", use_continuity=True)
    u = float(result.statistic)
    p = min(1.0, float(result.pvalue))
    z = float(norm.isf(p / 2)) if p < 1 else 0.0
    return {"U": u, "p": p, "A12": u / (m * n), "z": math.copysign(z, u - m * n / 2)}


# --- runs compared as rliable compares them -----------------------------------------------------


def iqm(values: Sequence[float] | np.ndarray) -> float:
    """The interquartile mean: the mean of the middle half of ``values`` (SciPy's
    ``trim_mean(values, 0.25)``; NaN for none), robust to the outlying runs a mean is not and
    using more of them than a median (Agarwal et al. 2021)."""
    from scipy.stats import trim_mean

    a = np.asarray(values, float)
    return float(trim_mean(a, 0.25)) if a.size else math.nan


def iqm_interval(
    values: Sequence[float], *, seed: int = 0, resamples: int = 2000, level: float = 0.95
) -> dict[str, float]:
    """The interquartile mean of ``values`` with a percentile bootstrap interval over the runs
    (SciPy's ``bootstrap``, ``seed``: its generator)."""
    a = np.asarray(values, float)
    point = iqm(a)
    if a.size < 2 or np.all(a == a[0]):
        return {"iqm": point, "low": point, "high": point}
    low, high = _bootstrap_ends((a,), _trim_mean, seed, resamples, level)
    return {"iqm": point, "low": low, "high": high}


def _bootstrap_ends(
    samples: tuple[np.ndarray, ...],
    statistic: Any,
    seed: int,
    resamples: int,
    level: float,
    *,
    paired: bool = False,
) -> tuple[float, float]:
    """The ends of SciPy's percentile bootstrap interval of ``statistic`` (vectorised over an
    ``axis``), each sample resampled apart, or with ``paired`` the samples' units together
    (``seed``: its NumPy generator)."""
    from scipy.stats import bootstrap

    res = bootstrap(
        samples,
        statistic,
        paired=paired,
        n_resamples=resamples,
        confidence_level=level,
        method="percentile",
        rng=np.random.default_rng(seed),
    )
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def _trim_mean(x: np.ndarray, axis: int) -> np.ndarray:
    from scipy.stats import trim_mean

    return np.asarray(trim_mean(x, 0.25, axis=axis))


def probability_of_improvement(
    a: Sequence[float],
    b: Sequence[float],
    *,
    seed: int = 0,
    resamples: int = 2000,
    level: float = 0.95,
) -> dict[str, float]:
    """P(a > b) + P(a = b)/2 over runs of ``a`` and ``b`` (a score where higher is better: a
    success rate; for evaluations to success pass them negated), with a percentile bootstrap
    interval that resamples each side's runs apart (stratified by side, as rliable does;
    SciPy's ``bootstrap``, ``seed``: its generator). 0.5: neither is better."""
    x, y = np.asarray(a, float), np.asarray(b, float)
    if x.size == 0 or y.size == 0:
        return {"p": math.nan, "low": math.nan, "high": math.nan}
    point = float(_improvement(x, y, -1))
    if x.size < 2 or y.size < 2 or np.all(np.concatenate([x, y]) == x[0]):
        return {"p": point, "low": point, "high": point}
    low, high = _bootstrap_ends((x, y), _improvement, seed, resamples, level)
    return {"p": point, "low": low, "high": high}


def _improvement(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
    """P(x > y) + P(x = y)/2 along ``axis`` (the runs) of each batch."""
    xa, ya = np.moveaxis(x, axis, -1), np.moveaxis(y, axis, -1)
    gt = (xa[..., :, None] > ya[..., None, :]).mean(axis=(-2, -1))
    eq = (xa[..., :, None] == ya[..., None, :]).mean(axis=(-2, -1))
    return np.asarray(gt + eq / 2)


def forward_transfer(
    times: Sequence[float | None],
    scratch: Sequence[float | None],
    budget: float,
    *,
    seed: int = 0,
    resamples: int = 2000,
    level: float = 0.95,
) -> dict[str, float]:
    """Forward transfer as Continual World normalises it (Wołczyk et al., NeurIPS 2021):
    ``(AUC - AUC_b) / (1 - AUC_b)``, with ``AUC`` the area under the solved-fraction curve of
    ``times`` (evaluations to success of each run; None: unsolved within ``budget``) over
    ``[0, budget]``, normalised to 1, and ``AUC_b`` that of the reference learned from
    ``scratch``. A run solved after ``t`` evaluations adds ``1 - t / budget`` to the area, an
    unsolved one 0, so ``AUC`` is their mean. 0: no transfer; 1: solved at once in every run;
    negative: slower than scratch. With a percentile bootstrap interval that resamples each
    side's runs apart (SciPy's ``bootstrap``); ``ft`` is NaN where the reference's AUC is 1
    (nothing left to transfer)."""
    a = np.asarray([0.0 if t is None else max(0.0, 1.0 - float(t) / budget) for t in times])
    b = np.asarray([0.0 if t is None else max(0.0, 1.0 - float(t) / budget) for t in scratch])
    nan = {"ft": math.nan, "low": math.nan, "high": math.nan, "auc": math.nan, "auc_b": math.nan}
    if a.size == 0 or b.size == 0:
        return nan
    point = float(_transfer(a, b, -1))
    if math.isnan(point):
        return {**nan, "auc": float(a.mean()), "auc_b": float(b.mean())}
    out = {
        "ft": point,
        "low": point,
        "high": point,
        "auc": float(a.mean()),
        "auc_b": float(b.mean()),
    }
    if a.size >= 2 and b.size >= 2 and not np.all(np.concatenate([a, b]) == a[0]):
        out["low"], out["high"] = _bootstrap_ends((a, b), _transfer, seed, resamples, level)
    return out


def paired_difference(
    a: Sequence[float],
    b: Sequence[float],
    *,
    seed: int = 0,
    resamples: int = 2000,
    level: float = 0.95,
) -> dict[str, float]:
    """The mean of ``a - b`` over paired units (e.g. the same mazes judged twice), with a
    percentile bootstrap interval that resamples the pairs (SciPy's ``bootstrap``,
    ``paired=True``; ``seed``: its NumPy generator): ``{"mean", "low", "high"}``."""
    x, y = np.asarray(a, float), np.asarray(b, float)
    if x.shape != y.shape:
        raise ValueError(f"paired_difference: {x.shape} against {y.shape} units")
    if x.size == 0:
        return {"mean": math.nan, "low": math.nan, "high": math.nan}
    point = float(np.mean(x - y))
    if x.size < 2 or np.all(x - y == (x - y)[0]):
        return {"mean": point, "low": point, "high": point}
    low, high = _bootstrap_ends((x, y), _mean_difference, seed, resamples, level, paired=True)
    return {"mean": point, "low": low, "high": high}


def _mean_difference(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.asarray(np.mean(x - y, axis=axis))


def _transfer(a: np.ndarray, b: np.ndarray, axis: int = -1) -> np.ndarray:
    """``(mean a - mean b) / (1 - mean b)`` along ``axis`` (NaN where ``mean b`` is 1)."""
    ma, mb = np.mean(a, axis=axis), np.mean(b, axis=axis)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.asarray(np.where(mb < 1.0, (ma - mb) / (1.0 - mb), np.nan))


def holm(pvalues: Sequence[float | None]) -> list[float | None]:
    """Holm's step-down adjustment of the p-values of one table's comparisons (Holm 1979):
    the k-th smallest of m is multiplied by m - k + 1, then made non-decreasing and capped at 1;
    an adjusted p-value below alpha rejects at family-wise error alpha. None (no test) stays
    None and does not count among the m."""
    idx = [i for i, p in enumerate(pvalues) if p is not None and not math.isnan(p)]
    out: list[float | None] = [None] * len(pvalues)
    m = len(idx)
    running = 0.0
    for k, i in enumerate(sorted(idx, key=lambda i: float(pvalues[i] or 0.0))):
        running = max(running, min(1.0, (m - k) * float(pvalues[i] or 0.0)))
        out[i] = running
    return out


def performance_profile(
    rates: Sequence[float], xs: np.ndarray | None = None
) -> dict[str, list[float]]:
    """The fraction of mazes whose success reaches at least ``x``, for each ``x`` of ``xs``
    (default 0.50, 0.51, ..., 1.00): one curve of the report's performance profile."""
    xs = np.round(np.linspace(0.5, 1.0, 51), 2) if xs is None else np.asarray(xs)
    r = np.asarray(rates, float)
    fraction = (r[None, :] >= xs[:, None] - 1e-12).mean(1) if r.size else np.zeros(len(xs))
    return {"x": [float(x) for x in xs], "fraction": [float(f) for f in fraction]}
