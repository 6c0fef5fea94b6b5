"""Equilibria of a CTRNN at constant inputs (mbn.networks.fixed_points)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from mbn.errors import MbnInputError
from mbn.networks.ctrnn import make_ctrnn, simulate
from mbn.networks.fixed_points import fixed_points


def _logistic(z):
    return 1.0 / (1.0 + np.exp(-z))


def test_a_self_exciting_neuron_has_two_stable_states_and_one_unstable_between():
    # y = 10 sigma(y - 5): symmetric about y = 5, where it is unstable (slope 10/4 > 1)
    net = make_ctrnn(W=[[10.0]], WE=[[1.0]], tau=[1.0], bias=[-5.0], gain=[1.0])
    points = fixed_points(net, [0.0])
    assert [p.stable for p in points] == [True, True, False]
    f = lambda y: -y + 10.0 * _logistic(y - 5.0)  # noqa: E731
    low, high = brentq(f, -1.0, 4.0), brentq(f, 6.0, 11.0)
    ys = sorted(float(p.y[0]) for p in points)
    assert ys == pytest.approx([low, 5.0, high], abs=1e-9)
    unstable = points[2]
    assert unstable.eigenvalues.real[0] == pytest.approx(-1.0 + 10.0 * 0.25, abs=1e-9)
    assert all(p.residual < 1e-9 for p in points)


def test_without_recurrence_the_one_equilibrium_is_the_input_drive():
    net = make_ctrnn(W=np.zeros((3, 3)), WE=[[1.0, 0, 0], [0, 2.0, 0], [0, 0, -3.0]], tau=[0.5] * 3)
    (point,) = fixed_points(net, [0.2, 0.3, 0.4])
    np.testing.assert_allclose(point.y, [0.2, 0.6, -1.2], atol=1e-12)
    np.testing.assert_allclose(point.eigenvalues.real, [-2.0, -2.0, -2.0], atol=1e-12)
    assert point.stable


def test_simulation_settles_on_a_stable_equilibrium_found():
    rng = np.random.default_rng(4)
    net = make_ctrnn(
        W=[[6.0, -4.0, 2.0], [5.0, 3.0, -6.0], [-3.0, 6.0, 4.0]],
        WE=np.eye(3),
        tau=[1.0, 1.0, 1.0],
        bias=[-2.0, -1.0, -3.0],
    )
    inputs = np.array([0.3, -0.2, 0.1])
    stable = [p for p in fixed_points(net, inputs) if p.stable]
    assert stable
    steps = 4000
    settled = 0
    for y0 in rng.uniform(-8.0, 8.0, (6, 3)):
        _, ys = simulate(net, y0, np.tile(inputs, (steps, 1)), 0.01, method="rk4")
        ys = np.asarray(ys)
        if np.max(np.abs(ys[-1] - ys[-200])) > 1e-4:
            continue  # not settled (a cycle): nothing to compare
        settled += 1
        assert min(np.max(np.abs(ys[-1] - p.y)) for p in stable) < 1e-3  # float32 simulation
    assert settled >= 3


def test_bad_inputs_are_refused():
    net = make_ctrnn(W=np.zeros((2, 2)), WE=np.zeros((2, 3)), tau=[1.0, 1.0])
    with pytest.raises(MbnInputError, match=r"inputs of shape \(3,\)"):
        fixed_points(net, [0.0, 0.0])
    with pytest.raises(MbnInputError, match="finite"):
        fixed_points(net, [0.0, float("nan"), 0.0])
