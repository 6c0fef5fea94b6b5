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


def _wilson_by_formula(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """The Wilson interval written out (the formula mbn computed by hand before SciPy)."""
    p = k / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return min(p, max(0.0, centre - half)), max(p, min(1.0, centre + half))


@pytest.mark.parametrize("n", [1, 5, 10, 11, 20, 187, 200, 204, 1000])
def test_the_wilson_interval_is_the_formula_s_to_a_rounding_error(n):
    from mbn.stats import wilson_interval

    for k in range(n + 1):
        lo, hi = wilson_interval(k, n)
        want = _wilson_by_formula(k, n)
        assert lo == pytest.approx(want[0], abs=1e-15) and hi == pytest.approx(want[1], abs=1e-15)
    # the observed rate at the ends exactly, nothing without trials
    assert wilson_interval(0, n)[0] == 0.0 and wilson_interval(n, n)[1] == 1.0
    assert all(math.isnan(x) for x in wilson_interval(0, 0))


def test_iqm_is_the_mean_of_the_middle_half_with_a_bootstrap_interval():
    from mbn.stats import iqm, iqm_interval

    values = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 100.0]  # the middle half: 2, 3, 4, 5
    assert iqm(values) == pytest.approx(3.5, abs=1e-12)
    out = iqm_interval(values, seed=1)
    assert out["iqm"] == pytest.approx(3.5) and out["low"] <= 3.5 <= out["high"]
    assert out["high"] < 100  # the outlier does not carry the interval
    assert iqm_interval(values, seed=1) == out  # same seed, same interval
    same = iqm_interval([0.7] * 5)
    assert same["low"] == same["iqm"] == same["high"] == pytest.approx(0.7, abs=1e-15)
    assert math.isnan(iqm([]))


def test_probability_of_improvement_counts_pairs_and_half_the_ties():
    from mbn.stats import probability_of_improvement

    a, b = [1.0, 1.0, 0.9, 0.8], [0.9, 0.7, 0.7, 0.6]
    # pairs: 1 > all 4 (x2), 0.9 > 3 and ties 1, 0.8 > 3: (4 + 4 + 3.5 + 3) / 16
    got = probability_of_improvement(a, b, seed=3)
    assert got["p"] == pytest.approx(14.5 / 16, abs=1e-12)
    assert 0.5 < got["low"] <= got["p"] <= got["high"] <= 1.0
    back = probability_of_improvement(b, a, seed=3)
    assert back["p"] == pytest.approx(1 - got["p"], abs=1e-12)
    assert probability_of_improvement([0.5] * 3, [0.5] * 4)["p"] == 0.5


def test_holm_adjusts_the_smallest_p_by_the_number_of_comparisons_step_down():
    from mbn.stats import holm

    # Holm (1979) step-down: sorted 0.01, 0.02, 0.03, 0.04 x 4, 3, 2, 1 -> 0.04, 0.06, 0.06, 0.06
    assert holm([0.03, 0.01, 0.04, 0.02]) == pytest.approx([0.06, 0.04, 0.06, 0.06])
    assert holm([0.5, None, 0.9]) == pytest.approx([1.0, None, 1.0], nan_ok=True)
    assert holm([0.001]) == [0.001] and holm([]) == []


def test_forward_transfer_is_continual_world_s_normalised_area_gain():
    from mbn.stats import forward_transfer

    budget = 1000
    # AUC: the mean over runs of 1 - t / budget (0 unsolved): programs 0.8, 0.6, 0 -> 0.4667;
    # scratch 0.2, 0, 0 -> 0.0667; FT = (0.4667 - 0.0667) / (1 - 0.0667) = 0.4286
    ft = forward_transfer([200, 400, None], [800, None, None], budget, resamples=500)
    assert ft["auc"] == pytest.approx(1.4 / 3) and ft["auc_b"] == pytest.approx(0.2 / 3)
    assert ft["ft"] == pytest.approx((1.4 / 3 - 0.2 / 3) / (1 - 0.2 / 3))
    assert ft["low"] <= ft["ft"] <= ft["high"]
    # the same runs: no transfer; slower than scratch: negative; all solved at once: 1
    assert forward_transfer([200, None], [200, None], budget)["ft"] == pytest.approx(0.0)
    assert forward_transfer([900, None], [100, 300], budget)["ft"] < 0
    assert forward_transfer([0, 0], [500, None], budget)["ft"] == pytest.approx(1.0)
    # nothing left to transfer where scratch solves at once; no runs: NaN
    assert math.isnan(forward_transfer([0, 10], [0, 0], budget)["ft"])
    assert math.isnan(forward_transfer([], [1, 2], budget)["ft"])
