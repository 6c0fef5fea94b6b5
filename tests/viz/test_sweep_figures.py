"""The sweep's box plots: one panel per group that has tests (an experiment without agreement
targets has an empty agreement group), and a clear error where nothing is left to draw."""

from __future__ import annotations

import matplotlib.image as mpimg
import pytest

from mbn.viz.sweep import rate_boxes


def test_an_empty_group_gets_no_panel(tmp_path):
    rates = {"a_jitter": [1.0, 0.9], "b_jitter": [0.5, float("nan")]}
    one = tmp_path / "one.png"
    rate_boxes(rates, {"a_jitter": 0.95}, one, [("Jittered", ["a_jitter", "b_jitter"])])
    two = tmp_path / "two.png"
    rate_boxes(
        rates,
        {"a_jitter": 0.95},
        two,
        [("Jittered", ["a_jitter", "b_jitter"]), ("Interpreter agreement (jittered)", [])],
    )
    # the empty group drew nothing: the same figure, one panel high
    assert mpimg.imread(one).shape == mpimg.imread(two).shape


def test_no_test_at_all_is_refused(tmp_path):
    with pytest.raises(ValueError, match="no test to draw"):
        rate_boxes({}, {}, tmp_path / "x.png", [("Agreement", [])])
