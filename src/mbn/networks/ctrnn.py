"""Continuous-time recurrent neural networks (paper eq. 1).

The dynamics of neuron ``i`` are

.. math::

    \\tau_i \\dot y_i = -y_i + \\sum_j W_{ij}\\, r_j + \\sum_k WE_{ik} I_k,
    \\qquad r_j = \\sigma(g_j (y_j + \\theta_j)),

with the logistic :math:`\\sigma`, membrane potential ``y``, firing rate ``r``, time constant
``tau``, optional bias ``theta`` (``bias``, default 0) and gain ``g`` (``gain``, default 1). With
the defaults this is exactly the paper's eq. 1. ``W[i, j]`` is the weight from neuron ``j`` to
neuron ``i`` (row = receiving neuron) and ``WE[i, k]`` the weight from external input ``k`` to
neuron ``i``.

Everything here is a pure function of immutable data, batched over any leading dimensions of the
state, the inputs and (by broadcasting) the parameters, and works in float32 and float64.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import warnings
from collections.abc import Callable
from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from mbn.errors import MbnInputError, UnstableStepError, UnstableStepWarning
from mbn.host import put
from mbn.io import check_fields, expect_object

Method = Literal["euler", "rk4"]
METHODS: tuple[Method, ...] = ("euler", "rk4")

__all__ = [
    "CTRNN",
    "METHODS",
    "Method",
    "check_dt",
    "euler_step",
    "euler_steps",
    "firing_rate",
    "integrate",
    "make_ctrnn",
    "matvec",
    "max_stable_dt",
    "rk4_step",
    "simulate",
    "step",
    "vector_field",
]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class CTRNN:
    """Parameters of a CTRNN. Build one with :func:`make_ctrnn`, which validates its arguments.

    Attributes:
        W: recurrent weights, shape ``(..., n, n)``; ``W[i, j]`` is from neuron j to neuron i.
        WE: input weights, shape ``(..., n, m)``; ``WE[i, k]`` is from input k to neuron i.
        tau: time constants in seconds, shape ``(..., n)``, all > 0.
        bias: biases ``theta`` added to the potential before the logistic, shape ``(..., n)``.
        gain: gains ``g`` multiplying ``y + theta`` in the logistic, shape ``(..., n)``.
    """

    W: Array
    WE: Array
    tau: Array
    bias: Array
    gain: Array

    @property
    def num_neurons(self) -> int:
        """Number of neurons ``n``."""
        return int(self.W.shape[-1])

    @property
    def num_inputs(self) -> int:
        """Number of external inputs ``m``."""
        return int(self.WE.shape[-1])

    @property
    def dtype(self) -> jnp.dtype:
        """Floating-point type of the parameters."""
        return self.W.dtype

    def replace(self, **changes: ArrayLike) -> CTRNN:
        """A copy with some fields replaced (no validation)."""
        return dataclasses.replace(self, **{k: jnp.asarray(v) for k, v in changes.items()})

    def to_dict(self) -> dict[str, list]:
        """Plain-Python form (nested lists) for JSON files."""
        return {
            f.name: np.asarray(getattr(self, f.name)).tolist() for f in dataclasses.fields(self)
        }

    @classmethod
    def from_dict(cls, data: dict, *, where: str = "network", dtype: object = None) -> CTRNN:
        """Inverse of :meth:`to_dict`, validated; ``where`` names the source in error messages."""
        check_fields(expect_object(data, where), where, ["W", "WE", "tau"], ["bias", "gain"])
        return make_ctrnn(
            data["W"],
            data["WE"],
            data["tau"],
            bias=data.get("bias"),
            gain=data.get("gain"),
            dtype=dtype,
            name=where,
        )


def _finite_array(value: ArrayLike, name: str, dtype: np.dtype) -> np.ndarray:
    """``value`` as a finite array of ``dtype``: numbers only (text such as ``"1.5"`` is refused,
    not parsed), finite, and within the range of ``dtype`` (a value finite in a JSON file can
    still be too large for float32)."""
    if isinstance(value, (str, bytes)) or _holds_text(value):
        raise MbnInputError(f"{name}: expected numbers, got text")
    try:
        wide = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError) as exc:
        raise MbnInputError(f"{name}: not an array of numbers ({exc})") from None
    if not np.all(np.isfinite(wide)):
        raise MbnInputError(f"{name}: contains non-finite values (NaN or inf)")
    limit = float(np.finfo(dtype).max)
    if wide.size and float(np.max(np.abs(wide))) > limit:
        raise MbnInputError(
            f"{name}: a value of magnitude {float(np.max(np.abs(wide))):.3g} is too large for "
            f"{np.dtype(dtype).name} (at most {limit:.3g})"
        )
    return wide.astype(dtype)


def _holds_text(value: object, depth: int = 0) -> bool:
    """Whether nested lists hold a string (what JSON gives for ``"1.5"``)."""
    if isinstance(value, (str, bytes)):
        return True
    if isinstance(value, (list, tuple)) and depth < 8:
        return any(_holds_text(v, depth + 1) for v in value)
    if isinstance(value, np.ndarray) and value.dtype.kind in "USO":
        return value.dtype.kind in "US" or any(_holds_text(v, depth + 1) for v in value.flat)
    return False


def make_ctrnn(
    W: ArrayLike,
    WE: ArrayLike,
    tau: ArrayLike,
    *,
    bias: ArrayLike | None = None,
    gain: ArrayLike | None = None,
    dtype: object = None,
    name: str = "network",
) -> CTRNN:
    """Build a validated :class:`CTRNN`.

    Args:
        W: ``(n, n)`` recurrent weights, ``W[i, j]`` from neuron j to neuron i. Leading batch
            dimensions are allowed and must agree across all arguments.
        WE: ``(n, m)`` input weights (``m`` may be 0).
        tau: time constants in seconds, a scalar (shared) or ``(n,)``; all must be > 0.
        bias: optional ``(n,)`` biases (default 0, as in the paper).
        gain: optional ``(n,)`` gains (default 1, as in the paper).
        dtype: floating dtype; default float64 when ``jax_enable_x64`` is on, else float32.
        name: what to call the network in error messages.

    Raises:
        MbnInputError: shapes that do not match, non-finite values, or ``tau <= 0``.
    """
    np_dtype = np.dtype(jnp.zeros(()).dtype if dtype is None else dtype)  # type: ignore[call-overload]
    if not np.issubdtype(np_dtype, np.floating):
        raise MbnInputError(f"{name}: dtype must be a floating type, got {np_dtype}")
    W_ = _finite_array(W, f"{name}.W", np_dtype)
    if W_.ndim < 2 or W_.shape[-1] != W_.shape[-2]:
        raise MbnInputError(f"{name}.W: must be square (n, n), got shape {W_.shape}")
    n = W_.shape[-1]
    batch = W_.shape[:-2]
    WE_ = _finite_array(WE, f"{name}.WE", np_dtype)
    if WE_.ndim < 2 or WE_.shape[-2] != n or WE_.shape[:-2] != batch:
        raise MbnInputError(
            f"{name}.WE: expected shape {(*batch, n, 'm')} to match W {W_.shape}, got {WE_.shape}"
        )

    def vector(value: ArrayLike | None, field: str, default: float) -> np.ndarray:
        arr = (
            np.full((*batch, n), default, np_dtype)
            if value is None
            else _finite_array(value, f"{name}.{field}", np_dtype)
        )
        try:
            return np.broadcast_to(arr, (*batch, n)).copy()
        except ValueError:
            raise MbnInputError(
                f"{name}.{field}: expected a scalar or shape {(*batch, n)}, got {arr.shape}"
            ) from None

    tau_ = vector(tau, "tau", 1.0)
    if np.any(tau_ <= 0):
        raise MbnInputError(f"{name}.tau: time constants must be > 0, got min {tau_.min()}")
    return CTRNN(
        W=put(W_),
        WE=put(WE_),
        tau=put(tau_),
        bias=put(vector(bias, "bias", 0.0)),
        gain=put(vector(gain, "gain", 1.0)),
    )


def firing_rate(net: CTRNN, y: ArrayLike) -> Array:
    """Firing rates ``sigma(gain * (y + bias))`` in (0, 1), shape of ``y`` ``(..., n)``."""
    return jax.nn.sigmoid(net.gain * (jnp.asarray(y) + net.bias))


def vector_field(net: CTRNN, y: ArrayLike, inputs: ArrayLike) -> Array:
    """Right-hand side ``dy/dt`` of eq. 1.

    Args:
        net: the network.
        y: membrane potentials ``(..., n)``.
        inputs: external inputs ``(..., m)``.

    Returns:
        ``dy/dt`` with the broadcast leading shape, in units of ``y`` per second.
    """
    r = firing_rate(net, y)
    drive = matvec(net.W, r) + matvec(net.WE, jnp.asarray(inputs))
    return (drive - y) / net.tau


#: Up to this many columns a matrix-vector product is written as a sum of column x scalar
#: broadcasts, which XLA fuses into one elementwise loop (about 8x faster than ``einsum`` for
#: 3-neuron networks on CPU; see ``benchmarks/``); wider matrices use ``einsum``.
_UNROLL_MAX_COLUMNS = 8


def matvec(a: Array, x: Array) -> Array:
    """``a @ x`` over the last axes with broadcast leading axes: ``a (..., n, k)``, ``x (..., k)``
    -> ``(..., n)``. Fast for the small matrices of CTRNNs (see ``_UNROLL_MAX_COLUMNS``)."""
    k = a.shape[-1]
    if k == 0:
        return jnp.zeros(jnp.broadcast_shapes(a.shape[:-1], (*x.shape[:-1], 1)), a.dtype)
    if k > _UNROLL_MAX_COLUMNS:
        return jnp.einsum("...ik,...k->...i", a, x)
    out = a[..., :, 0] * x[..., 0, None]
    for j in range(1, k):
        out = out + a[..., :, j] * x[..., j, None]
    return out


VectorField = Callable[[Array], Array]


def _euler(f: VectorField, y: Array, dt: ArrayLike) -> Array:
    return y + dt * f(y)


def _rk4(f: VectorField, y: Array, dt: ArrayLike) -> Array:
    k1 = f(y)
    k2 = f(y + 0.5 * dt * k1)
    k3 = f(y + 0.5 * dt * k2)
    k4 = f(y + dt * k3)
    return y + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


_INTEGRATORS: dict[str, Callable[[VectorField, Array, ArrayLike], Array]] = {
    "euler": _euler,
    "rk4": _rk4,
}


def integrator(method: str) -> Callable[[VectorField, Array, ArrayLike], Array]:
    """The one-step map ``(f, y, dt) -> y_next`` of ``method`` ('euler' or 'rk4')."""
    try:
        return _INTEGRATORS[method]
    except KeyError:
        raise MbnInputError(f"method: expected one of {METHODS}, got {method!r}") from None


def euler_step(net: CTRNN, y: ArrayLike, inputs: ArrayLike, dt: ArrayLike) -> Array:
    """One forward-Euler step of eq. 1 with inputs held constant over ``dt`` seconds."""
    y = jnp.asarray(y)
    return _euler(lambda z: vector_field(net, z, inputs), y, dt)


def euler_steps(net: CTRNN, y: ArrayLike, inputs: ArrayLike, dt: float, steps: int) -> Array:
    """``steps`` forward-Euler steps of ``dt`` seconds (a Python float) with the inputs held:
    :func:`euler_step` repeated, for one network and one state (``y (n,)``, ``inputs (m,)``).

    Mapped by :func:`jax.vmap` over a batch of states with the network held (one network for
    all, as a controller file's networks are: :class:`mbn.world.rollout.Shared`), it integrates
    the batch neuron by neuron — potentials ``(n, B)``, the batch along the fast axis — instead
    of robot by robot: the same operations (the recurrent sum ``W r`` as one matrix product),
    about 3 x faster for the 21-neuron interpreter at batch 4096 on a CPU, where a batch of
    ``(B, n)`` states broadcasts each neuron's parameters along the fast axis
    (``docs/speed.md``). Mapped with the network batched too, it is :func:`euler_step` mapped.
    """
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise MbnInputError(f"steps must be an integer >= 1, got {steps!r}")
    return _euler_steps(float(dt), steps)(net, jnp.asarray(y), jnp.asarray(inputs))


@functools.lru_cache(maxsize=64)
def _euler_steps(dt: float, steps: int) -> Callable[[CTRNN, Array, Array], Array]:
    def plain(net: CTRNN, y: Array, inputs: Array) -> Array:
        for _ in range(steps):
            y = euler_step(net, y, inputs, dt)
        return y

    run = jax.custom_batching.custom_vmap(plain)

    @run.def_vmap
    def batched(
        axis_size: int, in_batched: tuple[CTRNN, bool, bool], net: CTRNN, y: Array, inputs: Array
    ) -> tuple[Array, bool]:
        net_batched, y_batched, u_batched = in_batched
        if any(jax.tree.leaves(net_batched)) or net.W.ndim != 2 or y.ndim != 2:
            axes = (
                jax.tree.map(lambda b: 0 if b else None, net_batched),
                0 if y_batched else None,
                0 if u_batched else None,
            )
            return jax.vmap(plain, in_axes=axes, axis_size=axis_size)(net, y, inputs), True
        # one network, a batch of states (B, n): neuron-major
        yt = y.T if y_batched else jnp.broadcast_to(y[:, None], (y.shape[0], axis_size))
        u = inputs.T if u_batched else inputs[:, None]  # (m, B) or (m, 1)
        drive_in = _columns(net.WE, u)  # (n, B) or (n, 1)
        gain, bias, tau = net.gain[:, None], net.bias[:, None], net.tau[:, None]
        for _ in range(steps):
            r = jax.nn.sigmoid(gain * (yt + bias))
            yt = yt + dt * ((_columns(net.W, r) + drive_in - yt) / tau)
        return yt.T, True

    return run


def _columns(a: Array, x: Array) -> Array:
    """``a @ x`` for a matrix ``a (n, k)`` and columns ``x (k, B)``; small ``k`` as a sum of
    broadcasts that XLA fuses (:func:`matvec`)."""
    k = a.shape[-1]
    if k == 0:
        return jnp.zeros((a.shape[0], x.shape[-1]), a.dtype)
    if k > _UNROLL_MAX_COLUMNS:
        return a @ x
    out = a[:, 0, None] * x[None, 0]
    for j in range(1, k):
        out = out + a[:, j, None] * x[None, j]
    return out


def rk4_step(net: CTRNN, y: ArrayLike, inputs: ArrayLike, dt: ArrayLike) -> Array:
    """One classical Runge-Kutta step of eq. 1 with inputs held constant over ``dt`` seconds."""
    y = jnp.asarray(y)
    return _rk4(lambda z: vector_field(net, z, inputs), y, dt)


def step(
    net: CTRNN, y: ArrayLike, inputs: ArrayLike, dt: ArrayLike, method: Method = "rk4"
) -> Array:
    """One step of ``method`` ('euler' or 'rk4')."""
    y = jnp.asarray(y)
    return integrator(method)(lambda z: vector_field(net, z, inputs), y, dt)


def simulate(
    net: CTRNN,
    y0: ArrayLike,
    inputs: ArrayLike,
    dt: float,
    *,
    method: Method = "rk4",
    substeps: int = 1,
    record: bool = True,
) -> tuple[Array, Array | None]:
    """Integrate eq. 1 over a sequence of piecewise-constant inputs (jit-compiled ``lax.scan``).

    Args:
        net: the network (parameters may carry leading batch dimensions that broadcast).
        y0: initial potentials ``(..., n)``.
        inputs: ``(num_steps, ..., m)``; ``inputs[t]`` is held for step ``t``.
        dt: length of one step in seconds; each step is made of ``substeps`` integrator steps of
            ``dt / substeps``.
        method: 'euler' or 'rk4'.
        substeps: integrator steps per input step (>= 1).
        record: when true also return the potentials after every step.

    Returns:
        ``(y_final, ys)`` with ``ys`` of shape ``(num_steps, ..., n)`` (``None`` unless ``record``).
    """
    integrator(method)  # validate early, outside jit
    if substeps < 1:
        raise MbnInputError(f"substeps: must be >= 1, got {substeps}")
    return _simulate(net, jnp.asarray(y0), jnp.asarray(inputs), dt, method, substeps, record)


@functools.partial(jax.jit, static_argnames=("method", "substeps", "record"))
def _simulate(
    net: CTRNN,
    y0: Array,
    inputs: Array,
    dt: float | Array,
    method: str,
    substeps: int,
    record: bool,
) -> tuple[Array, Array | None]:
    return integrate(
        functools.partial(vector_field, net),
        y0,
        inputs,
        dt,
        method=method,
        substeps=substeps,
        record=record,
    )


def integrate(
    field: Callable[[Array, Array], Array],
    y0: Array,
    inputs: Array,
    dt: float | Array,
    *,
    method: str = "rk4",
    substeps: int = 1,
    record: bool = True,
) -> tuple[Array, Array | None]:
    """Integrate any vector field ``field(y, u) -> dy/dt`` over piecewise-constant inputs.

    The traceable core of :func:`simulate` (call it inside your own ``jit``); ``inputs`` has
    shape ``(num_steps, ...)`` and ``inputs[t]`` is held for step ``t``, made of ``substeps``
    integrator steps of ``dt / substeps``. Returns ``(y_final, ys or None)``.
    """
    one_step = integrator(method)
    h = dt / substeps

    def body(y: Array, u: Array) -> tuple[Array, Array | None]:
        def f(z: Array) -> Array:
            return field(z, u)

        def sub(_: int, z: Array) -> Array:
            return one_step(f, z, h)

        y = jax.lax.fori_loop(0, substeps, sub, y) if substeps > 1 else one_step(f, y, h)
        return y, (y if record else None)

    return jax.lax.scan(body, y0, inputs)


# --------------------------------------------------------------------------------------------
# Step-size stability (NumPy; a check at the boundary, not part of the hot path)
# --------------------------------------------------------------------------------------------


def _stability_polynomial(method: str, z: np.ndarray) -> np.ndarray:
    if method == "euler":
        return 1.0 + z
    return 1.0 + z + z**2 / 2.0 + z**3 / 6.0 + z**4 / 24.0


def _ray_limits(method: str, lam: np.ndarray) -> np.ndarray:
    """For each eigenvalue with Re < 0 the largest h with |R(h lam)| <= 1 (inf for Re >= 0)."""
    out = np.full(lam.shape, np.inf)
    decaying = lam.real < 0
    lam = lam[decaying]
    if lam.size == 0:
        return out
    if method == "euler":
        out[decaying] = -2.0 * lam.real / np.abs(lam) ** 2
        return out
    # RK4: the stability region along the ray from 0 in direction lam ends before |z| = 2.9.
    radii = np.linspace(0.0, 2.9, 2901)[1:]
    r_max = np.empty(lam.shape)
    for start in range(0, lam.size, _RAY_CHUNK):  # (chunk, 2900) at a time: bounded memory
        part = lam[start : start + _RAY_CHUNK]
        direction = part / np.abs(part)
        unstable = np.abs(_stability_polynomial(method, radii[None, :] * direction[:, None])) > 1.0
        first = np.where(unstable.any(axis=1), unstable.argmax(axis=1), radii.size)
        r_max[start : start + _RAY_CHUNK] = np.concatenate([[0.0], radii])[first]
    out[decaying] = r_max / np.abs(lam)
    return out


#: Eigenvalues whose RK4 rays :func:`_ray_limits` walks at once (a 2900-point ray each: 45 MiB
#: of complex numbers).
_RAY_CHUNK = 1024


#: The eigenvalue work :func:`max_stable_dt` may do, in units of ``n**3`` (one ``n x n``
#: eigenproblem costs about that): all 1026 corners (1024 random + the two extremes) up to 64
#: neurons, as before the bound; fewer random corners beyond (the two extremes always), so that
#: a 1000-neuron network costs two eigenproblems, not 1026 (seconds, not an hour).
CORNER_WORK = 1026 * 64**3
#: The most Jacobian entries :func:`max_stable_dt` holds at once (32 MiB of float64): the
#: corners are linearised a few at a time, never as one ``(corners, n, n)`` stack (8 GiB for
#: 1000 neurons).
_CHUNK_ENTRIES = 2**22


def max_stable_dt(net: CTRNN, method: Method = "rk4", *, max_corners: int = 1024) -> float:
    """Largest integration step (seconds) for which ``method`` is stable on ``net``.

    The Jacobian of eq. 1 is ``diag(1/tau) (-I + W diag(s))`` with the slopes
    ``s_j = gain_j sigma'(.)`` in ``[0, gain_j / 4]``. This function linearises at the extreme
    slopes (every corner of ``{0, gain/4}^n``, or ``max_corners`` random corners plus the two
    extremes when there are more) and returns the largest step for which every decaying mode lies
    inside the method's region of absolute stability. Growing modes (Re >= 0) are the network's own
    dynamics and do not limit the step. It is a heuristic (the worst case need not lie at a
    corner) that matches observed blow-ups well: a self-weight of -266 gives
    ``h/tau ~ 0.03`` for Euler. Only unbatched networks are accepted.

    Its cost is bounded: the corners are linearised a few at a time (``_CHUNK_ENTRIES``), and
    beyond 64 neurons fewer random corners are drawn, within ``CORNER_WORK`` (the two extremes
    always); up to 64 neurons the corners and the result are those of the unbounded check.
    """
    integrator(method)
    W = np.asarray(net.W, dtype=np.float64)
    if W.ndim != 2:
        raise MbnInputError(f"max_stable_dt: expects an unbatched network, got W shape {W.shape}")
    n = W.shape[0]
    tau = np.asarray(net.tau, dtype=np.float64)
    top = np.asarray(net.gain, dtype=np.float64) / 4.0
    if 2**n <= max_corners:
        corners = np.array(list(itertools.product((0.0, 1.0), repeat=n)))
    else:
        rng = np.random.default_rng(0)  # fixed: the check must be deterministic
        draws = min(max_corners, max(0, CORNER_WORK // max(n, 1) ** 3 - 2))
        corners = np.concatenate(
            [np.zeros((1, n)), np.ones((1, n)), rng.integers(0, 2, (draws, n))]
        ).astype(np.float64)
    eye = np.eye(n)[None]
    chunk = max(1, _CHUNK_ENTRIES // max(n * n, 1))
    limit = np.inf
    for start in range(0, len(corners), chunk):
        slopes = corners[start : start + chunk] * top  # (c, n)
        jac = (-eye + W[None] * slopes[:, None, :]) / tau[None, :, None]
        lam = np.linalg.eigvals(jac).ravel()
        limit = min(limit, float(np.min(_ray_limits(method, lam))))
    return float(limit)


def check_dt(
    net: CTRNN,
    dt: float,
    method: Method = "rk4",
    *,
    on_unstable: Literal["warn", "raise", "ignore"] = "warn",
    name: str = "dt",
) -> float:
    """Check a step against :func:`max_stable_dt`; return ``dt / max_stable_dt``.

    A ratio above 1 warns (:class:`~mbn.errors.UnstableStepWarning`) or raises
    (:class:`~mbn.errors.UnstableStepError`) according to ``on_unstable``.
    """
    if not np.isfinite(dt) or dt <= 0:
        raise MbnInputError(f"{name}: must be a finite number > 0, got {dt}")
    limit = max_stable_dt(net, method)
    ratio = float(dt / limit) if np.isfinite(limit) else 0.0
    if ratio > 1.0 and on_unstable != "ignore":
        message = (
            f"{name}={dt:g} s is above the stability limit {limit:.4g} s of {method} for this "
            f"network (ratio {ratio:.2f}); use a step <= {limit:.4g} s or more substeps"
        )
        if on_unstable == "raise":
            raise UnstableStepError(message)
        warnings.warn(message, UnstableStepWarning, stacklevel=2)
    return ratio
