"""Runs compared by evaluations to success (``mbn.stats``): censored quantiles, the
fraction solved, the ratio of medians with its bootstrap interval, Mann–Whitney U and A12. The
U test's p-values were computed independently (the normal approximation with tie and continuity
corrections, as SciPy's ``mannwhitneyu(..., method="asymptotic")`` gives them)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mbn.stats import censored_quantiles, mann_whitney, median_ratio, solved_curve


@pytest.mark.parametrize(
    ("a", "b", "u", "p"),
    [
        ([1, 2, 3], [4, 5, 6], 0.0, 0.0808555983700522),
        # censored runs (None) tie with each other, above every solved run
        ([1, 2, None, None], [3, None, None, None], 5.0, 0.4083519693259383),
        ([5, 1, 7, 3, 3, None], [2, 2, 8, None, None], 12.0, 0.64351499991621),
        # a run solved at the budget (10) needed fewer evaluations than one never solved
        # (SciPy on [1, 10, inf, 5] against [10, inf, inf])
        ([1, 10, None, 5], [10, None, None], 2.5, 0.2663799233424825),
    ],
)
def test_mann_whitney_matches_the_normal_approximation_with_ties(a, b, u, p):
    got = mann_whitney(a, b, budget=10)
    assert got["U"] == u
    assert got["p"] == pytest.approx(p, abs=1e-12)
    assert got["A12"] == pytest.approx(u / (len(a) * len(b)), abs=1e-15)


def test_a12_is_one_minus_itself_with_the_sides_swapped_and_half_when_all_tie():
    a, b = [10, 40, None, 20], [30, 50, 60]
    ab, ba = mann_whitney(a, b, 100), mann_whitney(b, a, 100)
    assert ab["A12"] + ba["A12"] == pytest.approx(1.0, abs=1e-15)
    assert ab["p"] == pytest.approx(ba["p"], abs=1e-15)
    tied = mann_whitney([None, None], [None], 100)
    assert tied["A12"] == 0.5 and tied["p"] == 1.0


def test_censored_quantiles_are_lower_bounds_where_they_fall_on_an_unsolved_run():
    q = censored_quantiles([100, 200, None, 300, None], budget=1000)
    # sorted: 100, 200, 300, 1000*, 1000*: the median is 300, q3 falls on a censored run
    assert (q["q1"], q["median"], q["q3"]) == (200.0, 300.0, None)
    assert q["median_censored"] is False
    q = censored_quantiles([100, None, None], budget=1000)
    assert q["median"] is None and q["median_censored"] is True
    # interpolating between a solved run and a censored one is no number of evaluations
    assert q["q1"] is None
    with pytest.raises(ValueError, match="outside"):
        censored_quantiles([1200], budget=1000)


def test_a_run_solved_at_the_budget_sorts_before_an_unsolved_one():
    """Solved at the last check (at the budget) is a number of evaluations; never solved is
    not: the median of 918, 1278, 5418 and one unsolved run is (1278 + 5418) / 2, whichever
    order the runs come in, and so is the bootstrap's point ratio."""
    for times in ([1278, None, 5418, 918], [5418, 1278, None, 918], [None, 918, 1278, 5418]):
        q = censored_quantiles(times, budget=5418)
        assert (q["q1"], q["median"], q["q3"]) == (1188.0, 3348.0, None)
        r = median_ratio(times, [3348, 3348], budget=5418, resamples=10)
        assert r["ratio"] == pytest.approx(1.0, abs=1e-15)


def test_solved_curve_counts_the_runs_solved_within_each_budget():
    grid, frac = solved_curve([100, None, 500], budget=1000, points=5)
    np.testing.assert_array_equal(grid, [0, 250, 500, 750, 1000])
    np.testing.assert_allclose(frac, [0, 1 / 3, 2 / 3, 2 / 3, 2 / 3], atol=1e-15)


def test_median_ratio_and_its_interval():
    a, b = [100, 200, 300, 400, 500], [400, 500, 600, 700, 800]
    r = median_ratio(a, b, budget=1000, resamples=4000, seed=1)
    assert r["ratio"] == pytest.approx(300 / 600, abs=1e-15)
    assert r["low"] is not None and r["high"] is not None
    assert r["low"] < 0.5 < r["high"] and r["low"] >= 100 / 800 and r["high"] <= 500 / 400
    assert median_ratio(a, b, budget=1000, resamples=4000, seed=1) == r  # seeded
    # a's median censored: the ratio has no upper bound
    r = median_ratio([None, None, 100], b, budget=1000, resamples=500)
    assert r["ratio"] is None and r["ratio_unbounded"] is True and r["high"] is None
    # b's censored: a is infinitely faster, the ratio is 0
    r = median_ratio(a, [None, None, 100], budget=1000, resamples=500)
    assert r["ratio"] == 0.0 and r["low"] == 0.0
    assert not math.isnan(r["undefined_resamples"])
