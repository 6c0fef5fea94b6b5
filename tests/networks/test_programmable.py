"""Tests of mbn.networks.programmable: the builder, its codec, exact and trained emulation."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mbn.errors import MbnInputError
from mbn.networks.ctrnn import make_ctrnn, max_stable_dt, simulate
from mbn.networks.emulation import EmulationConfig, piecewise_constant_inputs, published_check
from mbn.networks.multiplier import load_default
from mbn.networks.programmable import (
    Connection,
    Programmable,
    all_connections,
    build_interpreter,
    differing_connections,
    run,
    run_network,
)
from mbn.paper import W_RF, published_lf, published_rf
from mbn.precision import scope


@pytest.fixture(scope="session")
def mul():
    return load_default()


def test_differing_connections_of_the_published_networks(mul):
    found = differing_connections(published_rf(), published_lf(), margin=0.1)
    assert [str(p.connection) for p in found] == ["W[1,2]", "WE[1,0]", "WE[1,1]"]
    assert [p.connection.paper_name for p in found] == ["W_23", "WE_21", "WE_22"]
    # bounds: the two values plus 10 % of their span on each side
    np.testing.assert_allclose([p.lower for p in found], [-4 - 7.03, 0 - 1.8, -19 - 1.9])
    np.testing.assert_allclose([p.upper for p in found], [66.3 + 7.03, 18 + 1.8, 0 + 1.9])


def test_interpreter_wiring_follows_equation_2(mul):
    rf = published_rf(tau=0.5)
    progs = differing_connections(rf, published_lf())
    interp = build_interpreter(rf, progs, mul)
    n, q, K = 3, mul.num_neurons, 3
    assert interp.num_neurons == n + K * q
    assert interp.net.num_inputs == 3 + K
    W, WE = np.asarray(interp.net.W), np.asarray(interp.net.WE)
    mW, mWE = np.asarray(mul.net.W), np.asarray(mul.net.WE)
    # connection 0 is W[1,2]: direct weight min, multiplier fed by neuron 2 and program input 3
    block = slice(3, 3 + q)
    assert W[1, 2] == pytest.approx(progs[0].lower)
    np.testing.assert_array_equal(W[block, 2], mWE[:, 0])
    np.testing.assert_array_equal(WE[block, 3], mWE[:, 1])
    np.testing.assert_array_equal(W[block, block], mW)
    assert W[1, 3 + mul.output] == pytest.approx(progs[0].upper - progs[0].lower)
    # connection 1 is WE[1,0]: its multiplier reads external input 0
    block1 = slice(3 + q, 3 + 2 * q)
    assert WE[1, 0] == pytest.approx(progs[1].lower)
    np.testing.assert_array_equal(WE[block1, 0], mWE[:, 0])
    np.testing.assert_array_equal(WE[block1, 4], mWE[:, 1])
    # untouched connections keep their weights, multipliers run at tau / 10
    assert W[2, 0] == W_RF[2, 0]
    np.testing.assert_allclose(np.asarray(interp.net.tau)[3:], 0.05)
    np.testing.assert_allclose(np.asarray(interp.net.tau)[:3], 0.5)


def test_codec_round_trip_and_bounds(mul):
    rf = published_rf()
    progs = differing_connections(rf, published_lf())
    interp = build_interpreter(rf, progs, mul)
    p_rf, p_lf = interp.program_of(rf), interp.program_of(published_lf())
    np.testing.assert_allclose(interp.decode(p_rf), [66.3, 0.0, -19.0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(interp.decode(p_lf), [-4.0, 18.0, 0.0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(interp.encode(interp.lower), 0.0)
    np.testing.assert_allclose(interp.encode(interp.upper), 1.0)
    assert np.all((np.asarray(p_rf) > 0) & (np.asarray(p_rf) < 1))
    # a weight on its bound codes to 0 or 1 exactly, and every weight within them into [0, 1],
    # in the experiment's float32 too: a program is checked against [0, 1] exactly (controller
    # files), and on a GPU the division once rounded a weight on its upper bound to 1 + 1 ulp
    lo, hi = (np.asarray(b, np.float32) for b in (interp.lower, interp.upper))
    weights = np.concatenate([lo[None], hi[None], lo + (hi - lo) * np.linspace(0, 1, 101)[:, None]])
    weights = np.clip(weights, lo, hi)
    with scope("float32"):
        rf32 = published_rf(dtype=jnp.float32)
        interp32 = build_interpreter(rf32, progs, mul)
        codes = np.asarray(interp32.encode(weights))
    assert codes.dtype == np.float32
    assert np.all((codes >= 0) & (codes <= 1))
    np.testing.assert_array_equal(codes[:2], [[0, 0, 0], [1, 1, 1]])
    with pytest.raises(MbnInputError, match=r"W\[1,2\] = 100 is outside its bounds"):
        interp.encode([100.0, 0.0, 0.0])
    with pytest.raises(MbnInputError, match=r"program: values must be in \[0, 1\]"):
        interp.decode([0.5, 1.5, 0.5])


def emulation_error(interp, net, data, dt, exact, outputs=(1, 2)):
    y0 = jnp.zeros((data.shape[1], net.num_neurons))
    ref = run_network(net, y0, data, dt)
    emu = run(interp, y0, data, interp.program_of(net), dt, exact=exact)
    return np.asarray(jnp.max(jnp.abs(emu - ref)[..., list(outputs)], axis=(0, 2)))


def test_exact_mode_reproduces_the_published_networks(mul):
    rf, lf = published_rf(), published_lf()
    interp = build_interpreter(rf, differing_connections(rf, lf), mul)
    data = piecewise_constant_inputs(jax.random.key(0), 20, 2000, 200, 3)
    for net in (rf, lf):
        assert emulation_error(interp, net, data, 0.005, exact=True).max() <= 1e-6


SMALL_CHECK = EmulationConfig(num_sequences=40, seconds=10.0)


@pytest.mark.slow  # 10 s, and a known miss (xfail)
@pytest.mark.xfail(
    strict=True,
    reason="target not met: median 0.15, p95 0.59 with the shipped 3-neuron multiplier; the "
    "published LF is too sensitive to its programmable weights (docs/programmable.md)",
)
def test_trained_multiplier_emulates_the_published_networks(mul):
    # A smaller version of `mbn pnn check` (which runs 200 sequences of 20 s per program).
    result = published_check(jax.random.key(1), mul, SMALL_CHECK)
    assert result["trained"]["median_max_abs_output_diff"] <= 0.02
    assert result["trained"]["p95_max_abs_output_diff"] <= 0.1


def test_six_neuron_multiplier_emulates_the_published_rf_within_the_targets():
    result = published_check(jax.random.key(1), load_default(6), SMALL_CHECK)
    rf_part = result["per_program"][0]
    assert rf_part["median_max_abs_output_diff"] <= 0.02
    assert rf_part["p95_max_abs_output_diff"] <= 0.1


def test_published_lf_is_hypersensitive_to_its_programmable_weights():
    """Why the trained-multiplier target fails for LF: W_23 off by 0.1 (0.12 % of its programmable
    range, i.e. a multiplier error of 0.0012) already moves the outputs by more than 0.02, while
    the same error in RF moves them by less than 0.005."""
    lf, rf = published_lf(), published_rf()
    data = piecewise_constant_inputs(jax.random.key(0), 40, 2000, 200, 3)
    for net, low, high in ((lf, 0.02, np.inf), (rf, 0.0, 0.005)):
        y0 = simulate(net, jnp.zeros((40, 3)), jnp.broadcast_to(data[:1], (1000, 40, 3)), 0.005)[0]
        w = np.array(net.W)
        w[1, 2] += 0.1  # the paper's W_23
        nudged = make_ctrnn(w, net.WE, net.tau)
        ref = run_network(net, y0, data, 0.005)
        out = run_network(nudged, y0, data, 0.005)
        median = float(np.median(np.max(np.abs(out - ref)[..., 1:], axis=(0, 2))))
        assert low < median < high


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_fully_programmable_interpreter_is_exact_for_any_random_network(seed):
    rng = np.random.default_rng(seed)
    net = make_ctrnn(rng.uniform(-10, 10, (3, 3)), rng.uniform(-10, 10, (3, 3)), 0.5)
    interp = build_interpreter(net, all_connections(net, bound=10.0), load_default())
    assert interp.num_programs == 18
    data = piecewise_constant_inputs(jax.random.key(seed), 8, 1000, 100, 3)
    dt = min(0.005, 0.5 * max_stable_dt(net))
    assert emulation_error(interp, net, data, dt, exact=True, outputs=(0, 1, 2)).max() <= 1e-6


def test_interpreter_built_from_one_network_emulates_another(mul):
    # Build from A, program with B: the emulation must follow B, not A.
    rng = np.random.default_rng(3)
    a = make_ctrnn(rng.uniform(-5, 5, (3, 3)), rng.uniform(-5, 5, (3, 3)), 0.5)
    b = a.replace(W=a.W.at[0, 1].set(4.0), WE=a.WE.at[2, 2].set(-3.0))
    interp = build_interpreter(a, differing_connections(a, b), mul)
    data = piecewise_constant_inputs(jax.random.key(2), 10, 1000, 100, 3)
    assert emulation_error(interp, b, data, 0.005, exact=True, outputs=(0, 1, 2)).max() <= 1e-6
    assert emulation_error(interp, a, data, 0.005, exact=True, outputs=(0, 1, 2)).max() <= 1e-6


def test_input_connections_need_inputs_in_the_unit_interval(mul):
    rf = published_rf()
    interp = build_interpreter(rf, differing_connections(rf, published_lf()), mul)
    data = jnp.full((10, 3), 0.5).at[3, 1].set(1.7)
    with pytest.raises(MbnInputError, match=r"input\(s\) \[0, 1\] feed programmable WE"):
        run(interp, jnp.zeros(3), data, interp.program_of(rf), 0.005)


def test_program_outside_unit_interval_is_rejected(mul):
    rf = published_rf()
    interp = build_interpreter(rf, differing_connections(rf, published_lf()), mul)
    with pytest.raises(MbnInputError, match="program: values must be in"):
        run(interp, jnp.zeros(3), jnp.full((10, 3), 0.5), jnp.array([0.5, -0.1, 0.5]), 0.005)
    with pytest.raises(MbnInputError, match=r"program: expected shape \(\.\.\., 3\)"):
        run(interp, jnp.zeros(3), jnp.full((10, 3), 0.5), jnp.array([0.5, 0.5]), 0.005)


def test_time_varying_program_switches_the_emulated_network(mul):
    rf, lf = published_rf(), published_lf()
    interp = build_interpreter(rf, differing_connections(rf, lf), mul)
    data = jnp.full((4000, 3), 0.3)
    program = jnp.where(
        jnp.arange(4000)[:, None] < 2000, interp.program_of(rf), interp.program_of(lf)
    )
    out = run(interp, jnp.zeros(3), data, program, 0.005, exact=True)
    ref_rf = run_network(rf, jnp.zeros(3), data[:2000], 0.005)
    np.testing.assert_allclose(np.asarray(out[:2000]), np.asarray(ref_rf), atol=1e-9)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: Programmable(Connection("W", 0, 1), 1.0, 1.0), r"min 1.0 must be < max 1.0"),
        (lambda: Programmable(Connection("W", 0, 1), 0.0, np.inf), "bounds must be finite"),
        (lambda: Connection("V", 0, 1), "kind must be 'W' or 'WE'"),
        (lambda: Connection.parse("W[1;2]"), "expected 'W\\[i,j\\]'"),
    ],
)
def test_bad_connection_specs_are_named(make, message):
    with pytest.raises(MbnInputError, match=message):
        make()


def test_builder_rejects_bad_connection_sets(mul):
    rf = published_rf()
    c = Programmable(Connection("W", 0, 1), -500, 500)
    with pytest.raises(MbnInputError, match="listed twice"):
        build_interpreter(rf, [c, c], mul)
    with pytest.raises(MbnInputError, match=r"WE\[0,3\]: out of range"):
        build_interpreter(rf, [Programmable(Connection("WE", 0, 3), 0, 1)], mul)
    with pytest.raises(MbnInputError, match="at least one connection"):
        build_interpreter(rf, [], mul)


def test_connection_parse_round_trip():
    assert Connection.parse(" WE[2, 0] ") == Connection("WE", 2, 0)
    assert str(Connection.parse("W[1,2]")) == "W[1,2]"
