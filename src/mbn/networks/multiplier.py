"""The multiplier CTRNN ("mul", paper section 2.1): the model, its evaluation, its file format
and the shipped multipliers. Training by BPTT is :mod:`mbn.networks.multiplier_train`.

A multiplier is a small CTRNN with two external inputs ``x1, x2`` in (0, 1). Started from rest
(``y = 0``) with the inputs held constant, its last neuron's firing rate after ``T = 10 tau_m``
approximates ``x1 * x2``. Training differentiates through the integration (BPTT through a
``lax.scan``; a hand-written adjoint for Euler) and trains many random restarts at once, batched in
one array; the best restart by validation that also passes the fixed-point check is kept.

Choices (documented in ``docs/multiplier.md``):

* inputs enter every neuron (``WE`` is ``n x 2``), every neuron has a bias, gains are 1;
* loss: squared log-ratio ``(log out - log target)^2`` (relative error, as the paper's criterion)
  plus a small absolute-error term and a fixed-point penalty on ``|dy/dt|`` at ``T``; or, to
  fine-tune (``objective="minimax"``), a smooth maximum of the absolute error over a grid of the
  whole square plus one of the relative error where the product is not small;
* time is measured in units of ``tau_m`` (``tau = 1`` in the stored parameters); a multiplier
  embedded in a larger network is rescaled to the time constant it is given.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.resources
import json
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from mbn.errors import MbnInputError
from mbn.host import put
from mbn.io import (
    check_fields,
    expect_int,
    expect_number,
    expect_object,
    expect_str,
    read_json,
    write_json_atomic,
)
from mbn.networks.ctrnn import (
    CTRNN,
    Method,
    firing_rate,
    integrator,
    simulate,
)
from mbn.precision import NETWORKS, Precision, cast, dtype_of, scope

__all__ = [
    "FORMAT",
    "Multiplier",
    "dense_grid",
    "evaluate",
    "fixed_point_check",
    "load_default",
    "load_multiplier",
    "multiply",
    "relative_errors",
    "save_multiplier",
    "training_pairs",
    "validation_pairs",
]

FORMAT = "mbn.multiplier"
FORMAT_VERSION = 1

#: Holding time of the inputs, in units of tau_m (paper 2.1: T = 10 tau_m).
T_OVER_TAU = 10.0
#: Relative error bound of the paper's claim (5 %).
REL_TOL = 0.05
#: Largest allowed drift of the output between T and 2T, and between step h and h/10.
FIXED_POINT_TOL = 0.005


@dataclasses.dataclass(frozen=True)
class Multiplier:
    """A trained multiplier.

    Attributes:
        net: the CTRNN, with time constants in units of ``tau_m`` (all 1 for a trained one);
            inputs 0 and 1 are ``x1`` and ``x2``.
        output: index of the output neuron (its firing rate is the product).
        dt_over_tau: integration step (units of tau_m) the multiplier was trained and checked with.
        method: integrator it was trained with.
    """

    net: CTRNN
    output: int
    dt_over_tau: float = 0.1
    method: Method = "rk4"

    @property
    def num_neurons(self) -> int:
        """Number of neurons of the multiplier network."""
        return self.net.num_neurons


# --------------------------------------------------------------------------------------------
# Data sets
# --------------------------------------------------------------------------------------------


def training_pairs(num_per_axis: int = 10, dtype: Any = None) -> Array:
    """The paper's training set: ``num_per_axis**2`` pairs equally spaced in (0, 1)^2.

    The values are the cell centres ``(k - 1/2) / num_per_axis`` for ``k = 1..num_per_axis`` on
    each axis (0.05, 0.15, ..., 0.95 for the paper's 10). Returns shape ``(num_per_axis**2, 2)``.
    """
    axis = (np.arange(1, num_per_axis + 1) - 0.5) / num_per_axis
    x1, x2 = np.meshgrid(axis, axis, indexing="ij")
    return put(np.stack([x1.ravel(), x2.ravel()], axis=-1), dtype)


def validation_pairs(key: Array, num: int = 100, dtype: Any = None) -> Array:
    """``num`` random pairs uniform in (0, 1)^2, shape ``(num, 2)``.

    Always drawn in float32 (then cast), so that the same key gives the same pairs whether or
    not float64 is enabled.
    """
    pairs = jax.random.uniform(key, (num, 2), dtype=jnp.float32, minval=1e-6, maxval=1.0)
    return pairs.astype(dtype or jnp.zeros(()).dtype)


def dense_grid(num_per_axis: int = 101, dtype: Any = None) -> Array:
    """The closed grid ``linspace(0, 1, num_per_axis)^2``, shape ``(num_per_axis**2, 2)``.

    It includes the edges ``x = 0`` and ``x = 1`` (a harder test than the open square).
    """
    axis = np.linspace(0.0, 1.0, num_per_axis)
    x1, x2 = np.meshgrid(axis, axis, indexing="ij")
    return put(np.stack([x1.ravel(), x2.ravel()], axis=-1), dtype)


# --------------------------------------------------------------------------------------------
# Running a multiplier
# --------------------------------------------------------------------------------------------


def multiply(
    mul: Multiplier,
    pairs: ArrayLike,
    *,
    t_over_tau: float = T_OVER_TAU,
    dt_over_tau: float | None = None,
    method: Method | None = None,
    precision: Precision = NETWORKS,
) -> Array:
    """Output of ``mul`` for each pair after holding it ``t_over_tau`` time constants from rest,
    computed in ``precision`` (:mod:`mbn.precision`).

    Args:
        mul: the multiplier.
        pairs: ``(..., 2)`` inputs ``(x1, x2)``.
        t_over_tau: holding time in units of tau_m (default 10, the paper's T).
        dt_over_tau: integration step in units of tau_m (default: the one it was trained with).
        method: integrator (default: the one it was trained with).

    Returns:
        Firing rate of the output neuron, shape ``pairs.shape[:-1]``.
    """
    with scope(precision):
        net = cast(mul.net, precision)
        pairs = jax.device_put(np.asarray(pairs, dtype=net.dtype))
        h = mul.dt_over_tau if dt_over_tau is None else dt_over_tau
        num_steps = round(t_over_tau / h)
        integrator(method or mul.method)  # refused here, not inside the compiled program
        return _held_output(
            net, pairs, h, num_steps=num_steps, method=method or mul.method, output=mul.output
        )


@functools.partial(jax.jit, static_argnames=("num_steps", "method", "output"))
def _held_output(
    net: CTRNN, pairs: Array, h: float, *, num_steps: int, method: Method, output: int
) -> Array:
    """The output neuron's rate after ``num_steps`` steps of ``h`` with ``pairs`` held from
    rest: :func:`multiply`, compiled once per shape."""
    y0 = jnp.zeros((*pairs.shape[:-1], net.num_neurons), dtype=pairs.dtype)
    inputs = jnp.broadcast_to(pairs, (num_steps, *pairs.shape))
    y, _ = simulate(net, y0, inputs, h, method=method, record=False)
    return firing_rate(net, y)[..., output]


def fixed_point_check(
    mul: Multiplier, pairs: ArrayLike, *, precision: Precision = NETWORKS
) -> dict[str, float | bool]:
    """Check that the output at ``T`` is a fixed point and not a transient.

    Compares the output at ``T`` with the output at ``2T`` and with the output at ``T`` computed
    with a 10x smaller step. Both differences must stay within :data:`FIXED_POINT_TOL` on every
    pair.
    """
    out_t = multiply(mul, pairs, precision=precision)
    out_2t = multiply(mul, pairs, t_over_tau=2 * T_OVER_TAU, precision=precision)
    out_fine = multiply(mul, pairs, dt_over_tau=mul.dt_over_tau / 10, precision=precision)
    at_t = np.asarray(out_t)
    drift_2t = float(np.max(np.abs(np.asarray(out_2t) - at_t)))
    drift_step = float(np.max(np.abs(np.asarray(out_fine) - at_t)))
    return {
        "max_abs_diff_2T": drift_2t,
        "max_abs_diff_fine_step": drift_step,
        "passed": bool(max(drift_2t, drift_step) <= FIXED_POINT_TOL),
    }


def evaluate(
    mul: Multiplier,
    validation: ArrayLike,
    *,
    grid_points: int = 101,
    precision: Precision = NETWORKS,
) -> dict[str, Any]:
    """Metrics of a multiplier on a validation set and on the dense grid of (0, 1)^2, computed in
    ``precision`` (:mod:`mbn.precision`).

    Returns a JSON-ready dict: fraction of validation pairs within 5 % relative error, maximum
    relative error (over all pairs and over pairs whose product is >= 0.05), maximum and mean
    absolute error on the dense grid, and the fixed-point check.
    """
    with scope(precision):
        return _evaluate(mul, validation, grid_points, precision)


def _evaluate(
    mul: Multiplier, validation: ArrayLike, grid_points: int, precision: Precision
) -> dict[str, Any]:
    # the errors in NumPy (exactly rounded, as JAX's eager operations; none compiled)
    dtype = np.dtype(dtype_of(precision))
    validation = np.asarray(validation, dtype=dtype)
    target = validation[:, 0] * validation[:, 1]
    out = np.asarray(multiply(mul, validation, precision=precision))
    rel = np.abs(out - target) / target
    big = target >= 0.05
    grid = np.asarray(dense_grid(grid_points, dtype=dtype))
    grid_err = np.abs(
        np.asarray(multiply(mul, grid, precision=precision)) - grid[:, 0] * grid[:, 1]
    )
    return {
        "num_validation_pairs": int(validation.shape[0]),
        "fraction_within_5pct": float(np.mean(rel <= REL_TOL)),
        "max_rel_error": float(rel.max()),
        "max_rel_error_product_ge_0.05": float(rel[big].max()) if big.any() else 0.0,
        "max_abs_error_validation": float(np.max(np.abs(np.asarray(out - target)))),
        "grid_points_per_axis": grid_points,
        "max_abs_error_grid": float(grid_err.max()),
        "mean_abs_error_grid": float(grid_err.mean()),
        "fixed_point": fixed_point_check(mul, validation, precision=precision),
    }


def relative_errors(
    mul: Multiplier,
    pairs: ArrayLike,
    *,
    floor: float = 0.0,
    precision: Precision = NETWORKS,
) -> dict[str, Any]:
    """The paper's criterion on ``pairs``: the error relative to the target ``x1 x2``, over the
    pairs whose target is at least ``floor`` (0: all of them; the relative error is unbounded as
    the target goes to 0, since a logistic output never is 0). Returns a JSON-ready dict:
    ``pairs`` (counted), ``min_target``, ``fraction_within_5pct``, ``max_rel_error`` and the
    pair ``worst`` where it is largest."""
    with scope(precision):
        pairs = np.asarray(pairs, dtype=np.dtype(dtype_of(precision)))
        target = np.asarray(pairs[:, 0] * pairs[:, 1], np.float64)
        out = np.asarray(multiply(mul, pairs, precision=precision), np.float64)
    keep = target >= floor
    if not keep.any():
        raise MbnInputError(f"no pair has a target >= {floor:g}")
    rel = np.abs(out[keep] - target[keep]) / target[keep]
    worst = int(np.argmax(rel))
    return {
        "pairs": int(keep.sum()),
        "floor": float(floor),
        "min_target": float(target[keep].min()),
        "fraction_within_5pct": float(np.mean(rel <= REL_TOL)),
        "max_rel_error": float(rel[worst]),
        "worst": [float(v) for v in np.asarray(pairs, np.float64)[keep][worst]],
    }


# --------------------------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------------------------


def multiplier_to_dict(mul: Multiplier, metrics: dict | None = None) -> dict[str, Any]:
    """Self-describing JSON form of a multiplier (and optionally its metrics)."""
    from mbn._version import __version__
    from mbn.provenance import provenance

    data: dict[str, Any] = {
        "kind": FORMAT,
        "format_version": FORMAT_VERSION,
        "mbn_version": __version__,
        "provenance": provenance(),
        "num_neurons": mul.num_neurons,
        "inputs": ["x1", "x2"],
        "output_neuron": mul.output,
        "time_unit": "tau_m (time constants are relative; rescale when embedding)",
        "T_over_tau": T_OVER_TAU,
        "dt_over_tau": mul.dt_over_tau,
        "method": mul.method,
        "network": mul.net.to_dict(),
    }
    if metrics is not None:
        data["metrics"] = metrics
    return data


def multiplier_from_dict(data: Any, *, where: str = "multiplier") -> Multiplier:
    """Parse and validate :func:`multiplier_to_dict` output."""
    if not isinstance(data, dict) or data.get("kind") != FORMAT:
        kind = data.get("kind") if isinstance(data, dict) else type(data).__name__
        raise MbnInputError(f"{where}: not a multiplier file (kind {kind!r}, expected {FORMAT!r})")
    optional = ["format_version", "mbn_version", "provenance", "num_neurons", "inputs"]
    optional += ["output_neuron"]
    optional += ["time_unit", "T_over_tau", "dt_over_tau", "method", "metrics"]
    check_fields(data, where, ["kind", "network"], optional)
    if "metrics" in data:
        expect_object(data["metrics"], f"{where}: metrics")
    net = CTRNN.from_dict(data["network"], where=f"{where}: network")
    if net.num_inputs != 2:
        raise MbnInputError(
            f"{where}: a multiplier has 2 inputs, this network has {net.num_inputs}"
        )
    output = expect_int(data.get("output_neuron", net.num_neurons - 1), f"{where}: output_neuron")
    if not 0 <= output < net.num_neurons:
        raise MbnInputError(f"{where}: output_neuron {output!r} is not a neuron index")
    dt = expect_number(data.get("dt_over_tau", 0.1), f"{where}: dt_over_tau")
    if not 0 < dt <= 1:
        raise MbnInputError(f"{where}: dt_over_tau must be in (0, 1], got {dt!r}")
    method = expect_str(data.get("method", "rk4"), f"{where}: method", ("euler", "rk4"))
    return Multiplier(net=net, output=output, dt_over_tau=dt, method=method)  # type: ignore[arg-type]


def recorded_seed(data: dict[str, Any], where: str) -> int | None:
    """The training seed a multiplier file records (``metrics.training.seed``), checked, or
    None when it records none."""
    metrics = data.get("metrics")
    if metrics is None:
        return None
    training = expect_object(metrics, f"{where}: metrics").get("training")
    if training is None:
        return None
    seed = expect_object(training, f"{where}: metrics.training").get("seed")
    if seed is None:
        return None
    seed = expect_int(seed, f"{where}: metrics.training.seed")
    if not 0 <= seed < 2**32:
        raise MbnInputError(f"{where}: metrics.training.seed must be in [0, 2**32), got {seed}")
    return seed


def save_multiplier(path: str | Path, mul: Multiplier, metrics: dict | None = None) -> None:
    """Write a multiplier as JSON, atomically."""
    write_json_atomic(path, multiplier_to_dict(mul, metrics))


def load_multiplier(path: str | Path) -> Multiplier:
    """Read a multiplier JSON file written by :func:`save_multiplier`."""
    return multiplier_from_dict(read_json(path), where=str(path))


SHIPPED = {3: "multiplier_3.json", 6: "multiplier_6.json"}


@functools.cache
def _shipped_dict(num_neurons: int) -> dict[str, Any]:
    if num_neurons not in SHIPPED:
        raise MbnInputError(
            f"num_neurons: shipped multipliers have {sorted(SHIPPED)} neurons, not {num_neurons}"
        )
    text = importlib.resources.files("mbn.data").joinpath(SHIPPED[num_neurons]).read_text()
    return json.loads(text)


def load_default(num_neurons: int = 3) -> Multiplier:
    """The multiplier shipped with the package (3 neurons by default, also 6)."""
    return multiplier_from_dict(_shipped_dict(num_neurons), where=f"shipped {SHIPPED[num_neurons]}")


def shipped_metrics(num_neurons: int = 3) -> dict[str, Any]:
    """Metrics recorded when the shipped multiplier was trained."""
    return dict(_shipped_dict(num_neurons).get("metrics", {}))
