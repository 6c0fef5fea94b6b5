"""Tests of mbn.networks.multiplier: shipped multipliers meet the targets; BPTT training works."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.networks.ctrnn import make_ctrnn
from mbn.networks.multiplier import (
    FIXED_POINT_TOL,
    Multiplier,
    dense_grid,
    evaluate,
    fixed_point_check,
    load_default,
    load_multiplier,
    multiplier_from_dict,
    multiply,
    save_multiplier,
    shipped_metrics,
    training_pairs,
    validation_pairs,
)
from mbn.networks.multiplier_train import TrainConfig, train


def shipped_validation(num_neurons):
    seed = shipped_metrics(num_neurons)["training"]["seed"]
    _, k_val = jax.random.split(jax.random.key(seed))
    return validation_pairs(k_val)


def test_paper_training_set_is_a_10_by_10_grid_inside_the_unit_square():
    pairs = np.asarray(training_pairs())
    assert pairs.shape == (100, 2)
    np.testing.assert_allclose(np.unique(pairs[:, 0]), np.arange(0.05, 1.0, 0.1))


def test_dense_grid_is_101_by_101_including_the_edges():
    grid = np.asarray(dense_grid())
    assert grid.shape == (101 * 101, 2)
    assert grid.min() == 0.0 and grid.max() == 1.0


@pytest.mark.xfail(
    strict=True,
    reason="target a not met: the shipped 3-neuron multiplier has 86 % of validation pairs within "
    "5 % and a grid error of 0.15 at (1, 1) (docs/multiplier.md)",
)
def test_shipped_3_neuron_multiplier_meets_target_a():
    mul = load_default(3)
    assert mul.num_neurons == 3
    metrics = evaluate(mul, shipped_validation(3))
    assert metrics["fraction_within_5pct"] >= 0.90
    assert metrics["max_abs_error_grid"] <= 0.05
    assert metrics["fixed_point"]["passed"]


def test_shipped_6_neuron_multiplier_meets_target_b():
    mul = load_default(6)
    assert mul.num_neurons <= 6
    metrics = evaluate(mul, shipped_validation(6))
    assert metrics["max_rel_error_product_ge_0.05"] <= 0.05
    assert metrics["max_abs_error_grid"] <= 0.01
    assert metrics["fixed_point"]["passed"]


@pytest.mark.parametrize("num_neurons", [3, 6])
def test_shipped_multipliers_hold_a_fixed_point_and_their_recorded_accuracy(num_neurons):
    metrics = evaluate(load_default(num_neurons), shipped_validation(num_neurons))
    assert metrics["fixed_point"]["passed"]
    # what was measured when they were trained (docs/multiplier.md); a regression guard
    assert metrics["fraction_within_5pct"] >= {3: 0.86, 6: 0.94}[num_neurons]
    assert metrics["max_abs_error_grid"] <= {3: 0.16, 6: 0.008}[num_neurons]
    if num_neurons == 6:
        assert metrics["max_rel_error_product_ge_0.05"] <= 0.05


@pytest.mark.parametrize("num_neurons", [3, 6])
def test_shipped_metrics_match_a_fresh_evaluation(num_neurons):
    recorded = shipped_metrics(num_neurons)
    fresh = evaluate(load_default(num_neurons), shipped_validation(num_neurons))
    for key in ("fraction_within_5pct", "max_abs_error_grid"):
        assert fresh[key] == pytest.approx(recorded[key], abs=1e-4)


def test_multiplier_holds_its_output_on_other_validation_sets():
    # The fixed point must not depend on which pairs are looked at.
    mul = load_default(3)
    pairs = validation_pairs(jax.random.key(12345), 500)
    check = fixed_point_check(mul, pairs)
    assert check["passed"], check


def test_transient_exploiting_network_fails_the_fixed_point_check():
    # A slow neuron (tau = 20 tau_m) is still rising at T: its value at T is a transient.
    net = make_ctrnn(np.zeros((1, 1)), [[0.5, 0.5]], 20.0, bias=[-1.0])
    check = fixed_point_check(Multiplier(net=net, output=0), dense_grid(5))
    assert not check["passed"]
    assert check["max_abs_diff_2T"] > FIXED_POINT_TOL


def _fine_tune_shipped_3(objective: str, iterations: int) -> tuple[Multiplier, Multiplier, dict]:
    """The shipped 3-neuron multiplier, and one restart of it fine-tuned on a 21 x 21 grid."""
    base = load_default(3)
    key = jax.random.key(0)
    cfg = TrainConfig(
        num_neurons=3,
        objective=objective,
        method="euler",
        minimax_points=21,
        learning_rate=0.003,
        num_restarts=1,
        num_iterations=iterations,
        num_validation=50,
        grid_error_cap=1.0,
    )
    tuned, metrics = train(key, cfg, init=base, validation_key=key)
    return base, tuned, metrics


@pytest.mark.slow  # 10 s of training
def test_minimax_fine_tuning_lowers_the_largest_grid_error():
    # The shipped 3-neuron multiplier is 0.15 off at (1, 1); the minimax objective goes for it.
    base, _, after = _fine_tune_shipped_3("minimax", 200)
    before = evaluate(base, validation_pairs(jax.random.key(0), 50))["max_abs_error_grid"]
    assert after["max_abs_error_grid"] < 0.8 * before
    assert after["fixed_point"]["passed"]


@pytest.mark.slow
def test_count_fine_tuning_brings_more_of_the_grid_within_5_percent():
    # The soft count of grid points outside 5 % is the paper's criterion made differentiable.
    def within(mul: Multiplier) -> float:
        grid = dense_grid(101)
        target = np.asarray(grid[:, 0] * grid[:, 1])
        out = np.asarray(multiply(mul, grid))
        counted = target >= 0.01
        return float(np.mean(np.abs(out - target)[counted] / target[counted] <= 0.05))

    base, tuned, metrics = _fine_tune_shipped_3("count", 300)
    assert within(tuned) > within(base) + 0.004
    assert metrics["fixed_point"]["passed"]


def test_smooth_max_lies_within_temperature_log_n_below_the_max():
    from mbn.networks.multiplier_train import smooth_max

    v = jnp.asarray([[0.1, 0.5, 0.2, 0.5], [0.0, 0.0, 0.0, 0.3]])
    t = 0.01
    sm = np.asarray(smooth_max(v, t))
    top = np.asarray(v.max(-1))
    assert np.all(sm <= top + 1e-7)
    assert np.all(sm >= top - t * np.log(4) - 1e-7)


def test_unknown_training_objective_is_refused():
    with pytest.raises(MbnInputError, match="objective"):
        TrainConfig(objective="median")


@pytest.mark.slow
def test_bptt_training_reduces_the_error():
    # 4 restarts of 150 iterations bring the grid error to 0.23 of the untrained one (8 of 300:
    # 0.09, at 3 times the cost)
    cfg = TrainConfig(num_restarts=4, num_iterations=150, num_validation=50)
    untrained = TrainConfig(num_restarts=4, num_iterations=0, num_validation=50)
    key = jax.random.key(0)
    _, before = train(key, untrained)
    mul, after = train(key, cfg)
    assert after["mean_abs_error_grid"] < 0.5 * before["mean_abs_error_grid"]
    assert after["training"]["iterations_run"] == 150
    assert isinstance(mul, Multiplier)


@pytest.mark.slow
def test_training_is_deterministic():
    cfg = TrainConfig(num_restarts=4, num_iterations=50, num_validation=20)
    a, _ = train(jax.random.key(3), cfg)
    b, _ = train(jax.random.key(3), cfg)
    assert np.array_equal(np.asarray(a.net.W), np.asarray(b.net.W))


@pytest.mark.parametrize("method", ["rk4", "euler"])
def test_bptt_gradient_matches_finite_differences(method):
    from mbn.networks.multiplier_train import init_params, make_loss

    cfg = TrainConfig(dtype="float64", method=method)
    batched_loss = make_loss(cfg, training_pairs(4, jnp.float64))

    @jax.jit  # compiled once for the six differences (eager, its ops took most of 10 s)
    def loss(p):
        return batched_loss(jax.tree.map(lambda a: a[None], p))[0]

    params = init_params(jax.random.key(1), cfg, jnp.float64)
    params = jax.tree.map(lambda a: a * 0.3, params)
    grad = jax.jit(jax.grad(loss))(params)
    eps = 1e-6
    for name, index in (("W", (0, 1)), ("WE", (2, 0)), ("bias", (1,))):
        up = {**params, name: params[name].at[index].add(eps)}
        down = {**params, name: params[name].at[index].add(-eps)}
        fd = (loss(up) - loss(down)) / (2 * eps)
        np.testing.assert_allclose(float(grad[name][index]), float(fd), rtol=1e-5, atol=1e-8)


def test_hand_written_adjoint_matches_autodiff():
    """The Euler training path's custom VJP equals jax.grad through the plain lax.scan."""
    from mbn.networks.multiplier_train import euler_from_rest, rest_trajectory

    keys = jax.random.split(jax.random.key(7), 4)
    restarts, n = 3, 4
    W = jax.random.uniform(keys[0], (restarts, n, n), jnp.float64, -8, 8)
    WE = jax.random.uniform(keys[1], (restarts, n, 2), jnp.float64, -8, 8)
    bias = jax.random.uniform(keys[2], (restarts, n), jnp.float64, -8, 8)
    pairs = jax.random.uniform(keys[3], (17, 2), jnp.float64)
    weights = jnp.arange(1.0, n + 1)

    def via(f):
        return lambda *p: jnp.sum(jnp.sin(f(*p, pairs, 0.1, 60)) * weights)

    custom = jax.grad(via(euler_from_rest), argnums=(0, 1, 2))(W, WE, bias)
    plain = jax.grad(via(lambda *a: rest_trajectory(*a)[0]), argnums=(0, 1, 2))(W, WE, bias)
    for got, want in zip(custom, plain, strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12)


def test_save_and_load_round_trip(tmp_path):
    mul = load_default(3)
    save_multiplier(tmp_path / "m.json", mul, {"note": 1})
    again = load_multiplier(tmp_path / "m.json")
    pairs = dense_grid(11)
    np.testing.assert_array_equal(
        np.asarray(multiply(mul, pairs)), np.asarray(multiply(again, pairs))
    )


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"kind": "other"}, "not a multiplier file"),
        ([1, 2], "not a multiplier file"),
        ({"kind": "mbn.multiplier"}, "missing field 'network'"),
        (
            {
                "kind": "mbn.multiplier",
                "network": {"W": [[0.0]], "WE": [[0.0]], "tau": [1.0]},
            },
            "a multiplier has 2 inputs",
        ),
        (
            {
                "kind": "mbn.multiplier",
                "network": {"W": [[0.0]], "WE": [[0.0, 0.0]], "tau": [0.0]},
            },
            "tau: time constants must be > 0",
        ),
        (
            {
                "kind": "mbn.multiplier",
                "network": {"W": [[0.0]], "WE": [[0.0, 0.0]], "tau": [1.0]},
                "output_neuron": 3,
            },
            "output_neuron 3 is not a neuron index",
        ),
    ],
)
def test_bad_multiplier_files_are_named(data, message):
    with pytest.raises(MbnInputError, match=message):
        multiplier_from_dict(data, where="f.json")


def test_bad_training_settings_are_named():
    with pytest.raises(MbnInputError, match="num_restarts"):
        TrainConfig(num_restarts=0)
    with pytest.raises(MbnInputError, match="dt_over_tau"):
        TrainConfig(dt_over_tau=2.0)
    with pytest.raises(MbnInputError, match="num_neurons: shipped multipliers"):
        load_default(4)
