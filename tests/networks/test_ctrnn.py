"""Tests of mbn.networks.ctrnn: eq. 1 against SciPy, convergence order, dynamics, stability."""

from __future__ import annotations

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mbn.errors import MbnInputError, UnstableStepError, UnstableStepWarning
from mbn.networks.ctrnn import (
    check_dt,
    euler_step,
    euler_steps,
    firing_rate,
    make_ctrnn,
    max_stable_dt,
    rk4_step,
    simulate,
    vector_field,
)


def random_net(seed: int = 0, n: int = 4, m: int = 2, scale: float = 3.0):
    rng = np.random.default_rng(seed)
    return make_ctrnn(
        rng.uniform(-scale, scale, (n, n)),
        rng.uniform(-scale, scale, (n, m)),
        rng.uniform(0.5, 2.0, n),
        bias=rng.uniform(-1, 1, n),
        gain=rng.uniform(0.5, 1.5, n),
    )


def scipy_reference(net, y0, inputs, t_end):
    W, WE = np.asarray(net.W), np.asarray(net.WE)
    tau, bias, gain = np.asarray(net.tau), np.asarray(net.bias), np.asarray(net.gain)

    def f(_t, y):
        r = 1.0 / (1.0 + np.exp(-gain * (y + bias)))
        return (-y + W @ r + WE @ inputs) / tau

    sol = solve_ivp(f, (0.0, t_end), y0, method="DOP853", rtol=1e-12, atol=1e-12)
    return sol.y[:, -1]


def test_vector_field_is_equation_1_written_by_hand():
    net = make_ctrnn([[1.0, -2.0], [0.5, 0.0]], [[3.0], [-1.0]], [2.0, 0.5])
    y = jnp.array([0.3, -0.7])
    inputs = jnp.array([0.25])
    s = 1 / (1 + np.exp(-np.array([0.3, -0.7])))
    expected = np.array(
        [
            (-0.3 + 1.0 * s[0] - 2.0 * s[1] + 3.0 * 0.25) / 2.0,
            (0.7 + 0.5 * s[0] + 0.0 * s[1] - 1.0 * 0.25) / 0.5,
        ]
    )
    np.testing.assert_allclose(vector_field(net, y, inputs), expected, rtol=1e-14)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rk4_matches_solve_ivp(seed):
    net = random_net(seed)
    y0 = np.random.default_rng(seed + 10).normal(size=4)
    inputs = np.array([0.3, 0.8])
    num_steps, dt = 2000, 1e-3
    y, _ = simulate(net, y0, jnp.broadcast_to(inputs, (num_steps, 2)), dt, method="rk4")
    ref = scipy_reference(net, y0, inputs, num_steps * dt)
    np.testing.assert_allclose(np.asarray(y), ref, atol=1e-10, rtol=0)


def test_euler_matches_solve_ivp_at_small_step():
    net = random_net(3)
    y0 = np.zeros(4)
    inputs = np.array([0.5, 0.1])
    y, _ = simulate(net, y0, jnp.broadcast_to(inputs, (20000, 2)), 1e-4, method="euler")
    ref = scipy_reference(net, y0, inputs, 2.0)
    # Euler's global error is O(h): with h = 1e-4 s and O(1) derivatives it stays below 1e-3.
    np.testing.assert_allclose(np.asarray(y), ref, atol=1e-3, rtol=0)


@pytest.mark.parametrize(("method", "order"), [("euler", 1.0), ("rk4", 4.0)])
def test_convergence_order(method, order):
    net = random_net(4)
    y0 = np.array([0.5, -0.5, 1.0, 0.0])
    inputs = np.array([0.2, 0.9])
    t_end = 1.0
    ref = scipy_reference(net, y0, inputs, t_end)
    errors = []
    for num_steps in (20, 40, 80, 160):
        u = jnp.broadcast_to(inputs, (num_steps, 2))
        y, _ = simulate(net, y0, u, t_end / num_steps, method=method)
        errors.append(np.max(np.abs(np.asarray(y) - ref)))
    observed = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    np.testing.assert_allclose(observed, order, atol=0.15)


def test_linear_network_has_closed_form_solution():
    # With W = 0 each neuron is a first-order low-pass: y(t) = c + (y0 - c) exp(-t / tau).
    net = make_ctrnn(np.zeros((2, 2)), [[2.0], [-1.0]], [0.5, 2.0])
    y0 = np.array([1.0, 3.0])
    _y, ys = simulate(net, y0, jnp.full((1000, 1), 0.7), 1e-3, method="rk4")
    t = np.arange(1, 1001) * 1e-3
    c = np.array([1.4, -0.7])
    expected = c + (y0 - c) * np.exp(-t[:, None] / np.array([0.5, 2.0]))
    np.testing.assert_allclose(np.asarray(ys), expected, atol=1e-12)


def beer_oscillator():
    # Beer (1995), "On the dynamics of small continuous-time recurrent neural networks": this
    # 2-neuron CTRNN with self-excitation and antisymmetric cross-coupling has a stable limit cycle.
    # Beer's w12 = -1 is from neuron 1 to neuron 2, so it is W[1, 0] here (row = receiving neuron).
    return make_ctrnn([[4.5, 1.0], [-1.0, 4.5]], np.zeros((2, 0)), 1.0, bias=[-2.75, -1.75])


def oscillation_period(ys, dt):
    x = np.asarray(ys)[:, 0]
    x = x - x.mean()
    up = np.nonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
    # linear interpolation of the upward zero crossings
    times = (up + x[up] / (x[up] - x[up + 1])) * dt
    return np.diff(times)


def test_two_neuron_oscillator_has_a_stable_limit_cycle():
    net = beer_oscillator()
    dt = 0.01
    _, ys = simulate(net, jnp.zeros(2), jnp.zeros((20000, 0)), dt, method="rk4")
    tail = np.asarray(ys)[5000:]  # after 50 s of transient; the period is about 29 s
    rates = np.asarray(firing_rate(net, tail))
    # it keeps oscillating with a large amplitude (no convergence to a fixed point) ...
    assert rates[:, 0].max() - rates[:, 0].min() > 0.5
    periods = oscillation_period(tail, dt)
    assert len(periods) >= 3
    # ... with a constant period (a limit cycle, not a transient) ...
    assert np.ptp(periods) < 1e-3 * periods.mean()

    # ... equal to the period of the SciPy solution.
    def f(_t, y):
        return -y + np.asarray(net.W) @ (1 / (1 + np.exp(-(y + np.asarray(net.bias)))))

    t_eval = np.arange(5001, 20001) * dt
    sol = solve_ivp(f, (0, 200.0), [0.0, 0.0], t_eval=t_eval, rtol=1e-11, atol=1e-11)
    ref_periods = oscillation_period(sol.y.T, dt)
    np.testing.assert_allclose(periods.mean(), ref_periods.mean(), rtol=1e-5)


def test_simulation_is_bitwise_deterministic():
    net = random_net(5)
    u = jax.random.uniform(jax.random.key(0), (500, 2))
    a = simulate(net, jnp.zeros(4), u, 0.01)[1]
    b = simulate(net, jnp.zeros(4), u, 0.01)[1]
    assert np.array_equal(np.asarray(a), np.asarray(b))


def test_batched_over_leading_dimensions_equals_one_by_one():
    net = random_net(6)
    key = jax.random.key(1)
    y0 = jax.random.normal(key, (3, 5, 4))
    u = jax.random.uniform(jax.random.fold_in(key, 1), (50, 3, 5, 2))
    y, _ = simulate(net, y0, u, 0.02, method="rk4", substeps=3)
    for a in range(3):
        for b in range(5):
            y1, _ = simulate(net, y0[a, b], u[:, a, b], 0.02, method="rk4", substeps=3)
            np.testing.assert_allclose(np.asarray(y[a, b]), np.asarray(y1), rtol=1e-13, atol=1e-13)


def test_batched_parameters_broadcast_against_state():
    nets = [random_net(s) for s in (7, 8)]
    stacked = jax.tree.map(lambda *a: jnp.stack(a), *nets)
    u = jnp.full((30, 2, 2), 0.4)
    y, _ = simulate(stacked, jnp.zeros((2, 4)), u, 0.05)
    for k, net in enumerate(nets):
        y1, _ = simulate(net, jnp.zeros(4), u[:, k], 0.05)
        np.testing.assert_allclose(np.asarray(y[k]), np.asarray(y1), rtol=1e-13)


def test_substeps_equal_smaller_steps():
    net = random_net(9)
    u = jnp.full((10, 2), 0.5)
    y_sub, _ = simulate(net, jnp.zeros(4), u, 0.1, method="euler", substeps=4)
    y_fine, _ = simulate(net, jnp.zeros(4), jnp.repeat(u, 4, axis=0), 0.025, method="euler")
    np.testing.assert_allclose(np.asarray(y_sub), np.asarray(y_fine), rtol=1e-13)


@pytest.mark.parametrize("n", [3, pytest.param(12, marks=pytest.mark.slow)])
def test_euler_steps_mapped_over_a_batch_equal_euler_steps_one_by_one(n):
    """``euler_steps`` under ``jax.vmap``: a held network (integrated neuron-major), a batched
    one (mapped ``euler_step``), inputs batched or held, a state held, and a vmap inside a vmap
    all equal ``euler_step`` repeated robot by robot, to rounding (float64)."""
    net = random_net(3, n=n, m=5)
    rng = np.random.default_rng(1)
    b, steps, h = 7, 20, 0.005
    y = jnp.asarray(rng.normal(size=(b, n)))
    u = jnp.asarray(rng.uniform(0, 1, (b, 5)))

    @jax.jit  # the loop unrolled in one program: the same operations, step by step
    def by_hand(net, y, u):
        for _ in range(steps):
            y = euler_step(net, y, u, h)
        return y

    want = np.stack([np.asarray(by_hand(net, y[i], u[i])) for i in range(b)])
    run = lambda net, y, u: euler_steps(net, y, u, h, steps)  # noqa: E731
    held = jax.jit(jax.vmap(run, in_axes=(None, 0, 0)))(net, y, u)
    np.testing.assert_allclose(np.asarray(held), want, rtol=0, atol=1e-12)
    nets = jax.tree.map(lambda a: jnp.broadcast_to(a, (b, *a.shape)), net)
    mapped = jax.vmap(run)(nets, y, u)
    np.testing.assert_allclose(np.asarray(mapped), want, rtol=0, atol=1e-12)
    one_input = jax.vmap(run, in_axes=(None, 0, None))(net, y, u[0])
    want_one = np.stack([np.asarray(by_hand(net, y[i], u[0])) for i in range(b)])
    np.testing.assert_allclose(np.asarray(one_input), want_one, rtol=0, atol=1e-12)
    one_state = jax.vmap(run, in_axes=(None, None, 0))(net, y[0], u)
    want_state = np.stack([np.asarray(by_hand(net, y[0], u[i])) for i in range(b)])
    np.testing.assert_allclose(np.asarray(one_state), want_state, rtol=0, atol=1e-12)
    # two networks held for a batch of robots, each robot running both (a vmap in a vmap)
    pair = jax.tree.map(lambda a: jnp.stack([a, a * 0.5]), net)
    both = jax.vmap(lambda y, u: jax.vmap(run, in_axes=(0, None, None))(pair, y, u))(y, u)
    half = jax.tree.map(lambda a: a * 0.5, net)
    np.testing.assert_allclose(np.asarray(both[:, 0]), want, rtol=0, atol=1e-12)
    want_half = np.stack([np.asarray(by_hand(half, y[i], u[i])) for i in range(b)])
    np.testing.assert_allclose(np.asarray(both[:, 1]), want_half, rtol=0, atol=1e-12)
    # unmapped, it is euler_step repeated
    np.testing.assert_allclose(np.asarray(run(net, y[0], u[0])), want[0], rtol=0, atol=1e-12)
    with pytest.raises(MbnInputError, match="steps must be an integer"):
        euler_steps(net, y[0], u[0], h, 0)


def test_single_steps_agree_with_simulate():
    net = random_net(10)
    y0 = jnp.array([0.1, 0.2, -0.3, 0.0])
    u = jnp.array([0.6, 0.3])
    for method, fn in (("euler", euler_step), ("rk4", rk4_step)):
        y, _ = simulate(net, y0, u[None], 0.03, method=method)
        np.testing.assert_allclose(np.asarray(fn(net, y0, u, 0.03)), np.asarray(y), rtol=1e-14)


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_float32_and_float64_are_kept(dtype):
    net = random_net(11)
    net = jax.tree.map(lambda a: a.astype(dtype), net)
    y, ys = simulate(net, jnp.zeros(4, dtype), jnp.zeros((5, 2), dtype), 0.01)
    assert y.dtype == dtype and ys.dtype == dtype


def test_float32_tracks_float64():
    net64 = random_net(12)
    net32 = jax.tree.map(lambda a: a.astype(jnp.float32), net64)
    u = jnp.full((200, 2), 0.5)
    y64, _ = simulate(net64, jnp.zeros(4), u, 0.01)
    y32, _ = simulate(net32, jnp.zeros(4, jnp.float32), u.astype(jnp.float32), 0.01)
    np.testing.assert_allclose(np.asarray(y32), np.asarray(y64), atol=1e-5)


def test_stability_limit_of_a_strong_self_inhibition():
    # One neuron with self-weight -266: the linearisation at the steepest slope has eigenvalue
    # -(1 + 266/4)/tau, so forward Euler is stable for h <= 2 tau / 67.5 (~0.03 tau).
    net = make_ctrnn([[-266.0]], np.zeros((1, 0)), 0.5)
    np.testing.assert_allclose(max_stable_dt(net, "euler"), 2 * 0.5 / 67.5, rtol=1e-12)
    # RK4's real-axis stability limit is 2.785.
    np.testing.assert_allclose(max_stable_dt(net, "rk4"), 2.785 * 0.5 / 67.5, rtol=2e-3)


@pytest.mark.parametrize("method", ["euler", "rk4"])
def test_steps_above_the_limit_blow_up_and_below_it_do_not(method):
    # Self-inhibited neuron held at its steepest point (bias 0, fixed point at y = 0 with a
    # balancing input) oscillates with growing amplitude above the limit.
    net = make_ctrnn([[-266.0]], [[133.0]], 0.5)
    limit = max_stable_dt(net, method)
    u = jnp.ones((400, 1))
    y_ok, _ = simulate(net, jnp.array([0.01]), u, 0.9 * limit, method=method)
    y_bad, _ = simulate(net, jnp.array([0.01]), u, 1.2 * limit, method=method)
    assert abs(float(y_ok[0])) < 1e-3
    assert abs(float(y_bad[0])) > 0.1


def test_check_dt_warns_or_raises_above_the_limit():
    net = make_ctrnn([[-266.0]], np.zeros((1, 0)), 0.5)
    limit = max_stable_dt(net, "euler")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert check_dt(net, 0.5 * limit, "euler") == pytest.approx(0.5)
    with pytest.warns(UnstableStepWarning, match="stability limit"):
        check_dt(net, 2 * limit, "euler")
    with pytest.raises(UnstableStepError, match=r"dt=.* above the stability limit"):
        check_dt(net, 2 * limit, "euler", on_unstable="raise")
    with pytest.raises(MbnInputError, match="dt: must be"):
        check_dt(net, -1.0)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"W": np.zeros((2, 3))}, r"W: must be square"),
        ({"WE": np.zeros((3, 2))}, r"WE: expected shape"),
        ({"tau": [1.0, 0.0]}, r"tau: time constants must be > 0"),
        ({"tau": [1.0, 1.0, 1.0]}, r"tau: expected a scalar or shape"),
        ({"W": [[np.nan, 0], [0, 0]]}, r"W: contains non-finite"),
        ({"bias": [np.inf, 0]}, r"bias: contains non-finite"),
        ({"W": [["a", 0], [0, 0]]}, r"W: expected numbers, got text"),
        ({"W": [["1.5", 0], [0, 0]]}, r"W: expected numbers, got text"),
        ({"W": [[1, 2], [3]]}, r"W: not an array of numbers"),
    ],
)
def test_bad_parameters_are_named(kwargs, message):
    args = {"W": np.zeros((2, 2)), "WE": np.zeros((2, 1)), "tau": 1.0, **kwargs}
    with pytest.raises(MbnInputError, match=message):
        make_ctrnn(args.pop("W"), args.pop("WE"), args.pop("tau"), **args)


def test_unknown_method_is_rejected():
    net = random_net()
    with pytest.raises(MbnInputError, match="method"):
        simulate(net, jnp.zeros(4), jnp.zeros((3, 2)), 0.1, method="midpoint")


def _unbounded_max_stable_dt(net, method, max_corners=1024):
    """The check as it was before its cost was bounded: every corner's Jacobian in one stack,
    every eigenvalue's RK4 ray in one array."""
    import itertools

    W = np.asarray(net.W, dtype=np.float64)
    n = W.shape[0]
    tau = np.asarray(net.tau, dtype=np.float64)
    top = np.asarray(net.gain, dtype=np.float64) / 4.0
    if 2**n <= max_corners:
        corners = np.array(list(itertools.product((0.0, 1.0), repeat=n)))
    else:
        rng = np.random.default_rng(0)
        corners = np.concatenate(
            [np.zeros((1, n)), np.ones((1, n)), rng.integers(0, 2, (max_corners, n))]
        ).astype(np.float64)
    slopes = corners * top
    jac = (-np.eye(n)[None] + W[None] * slopes[:, None, :]) / tau[None, :, None]
    lam = np.linalg.eigvals(jac).ravel()
    lam = lam[lam.real < 0]
    if method == "euler":
        return float(np.min(-2.0 * lam.real / np.abs(lam) ** 2, initial=np.inf))
    radii = np.linspace(0.0, 2.9, 2901)[1:]
    z = radii[None, :] * (lam / np.abs(lam))[:, None]
    unstable = np.abs(1.0 + z + z**2 / 2.0 + z**3 / 6.0 + z**4 / 24.0) > 1.0
    first = np.where(unstable.any(axis=1), unstable.argmax(axis=1), radii.size)
    return float(np.min(np.concatenate([[0.0], radii])[first] / np.abs(lam), initial=np.inf))


@pytest.mark.parametrize(
    ("n", "method"),
    [(n, "euler") for n in (1, 3, 10, 11, 40, 64)]
    + [(3, "rk4")]
    + [pytest.param(n, "rk4", marks=pytest.mark.slow) for n in (10, 11)],
)
def test_max_stable_dt_is_the_unbounded_checks_up_to_64_neurons(n, method):
    """The bounded check gives exactly the verdicts of the unbounded one on the networks it was
    made for (every corner up to 10 neurons, the same 1026 corners up to 64)."""
    rng = np.random.default_rng(n)
    net = make_ctrnn(
        rng.normal(0.0, 30.0, (n, n)),
        np.zeros((n, 3)),
        rng.uniform(0.2, 1.0, n),
        gain=rng.uniform(0.5, 2.0, n),
    )
    assert max_stable_dt(net, method) == _unbounded_max_stable_dt(net, method)  # bit for bit


def test_max_stable_dt_of_1000_neurons_holds_a_bounded_memory():
    """A 1000-neuron network is linearised at its two extreme corners, a few Jacobians at a
    time: under 256 MiB (the unbounded check stacked 1026 of them: 8 GiB), and its limit is that
    of those corners. W is triangular with diagonal d, so the eigenvalues are known: at rest
    -1/tau (Euler: h <= 2 tau = 1 s), at the steepest slopes (-1 + d/4)/tau, the most negative
    (-1 - 40/4)/0.5 = -22 (h <= 2/22 s)."""
    import tracemalloc

    n = 1000
    rng = np.random.default_rng(0)
    W = np.triu(rng.normal(0.0, 1.0, (n, n)), 1) + np.diag(np.linspace(-40.0, 2.0, n))
    net = make_ctrnn(W, np.zeros((n, 3)), 0.5)
    tracemalloc.start()
    try:
        limit = max_stable_dt(net, "euler")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 256 * 2**20, peak
    np.testing.assert_allclose(limit, 2.0 / 22.0, rtol=1e-9)
