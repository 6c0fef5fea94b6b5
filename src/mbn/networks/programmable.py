"""Programmable networks (paper section 2, eq. 2): a CTRNN turned into a fixed-weight interpreter.

Given a network ``S`` and a set of its connections, each with a bound ``(min, max)``, the builder
returns one fixed-weight CTRNN, the *interpreter*, that contains the neurons of ``S`` plus one
multiplier sub-network per chosen connection. For a recurrent connection ``W[i, j]`` (from neuron j
to neuron i):

1. the firing rate of neuron j becomes input ``x1`` of the multiplier,
2. a new external *program* input ``p = (W[i, j] - min) / (max - min)`` (eq. 2) becomes ``x2``,
3. the multiplier's output neuron feeds neuron i with weight ``max - min``,
4. a direct connection j -> i keeps the weight ``min``,

so that neuron i receives ``min * r_j + (max - min) * mul(r_j, p) ~ W[i, j] * r_j``. An input
connection ``WE[i, k]`` is handled the same way with the external input ``I_k`` in place of
``r_j``; since a multiplier only multiplies numbers in (0, 1), such a connection is programmable
only for inputs in [0, 1] (checked by :func:`check_data_inputs` and :func:`run`).

The multiplier neurons run with the time constant ``tau_ratio * tau_i`` of the receiving neuron
(``tau_ratio = 0.1`` by default, the paper's "an order of magnitude" smaller). The interpreter's
inputs are the original inputs followed by one program input per connection, in the order given.

:func:`run` also has an *exact* mode in which every multiplier is replaced by the exact product,
which separates construction errors (wiring, codec) from approximation errors of the multiplier.
"""

from __future__ import annotations

import dataclasses
import functools
import re
from collections.abc import Sequence
from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from mbn.errors import MbnInputError
from mbn.networks.ctrnn import (
    CTRNN,
    Method,
    firing_rate,
    integrate,
    integrator,
    make_ctrnn,
    vector_field,
)
from mbn.networks.multiplier import Multiplier
from mbn.networks.structured import BlockNet, block_exact_field, block_field, from_interpreter

__all__ = [
    "DEFAULT_TAU_RATIO",
    "Connection",
    "Interpreter",
    "Programmable",
    "all_connections",
    "build_interpreter",
    "check_data_inputs",
    "differing_connections",
    "run",
    "run_network",
    "weights_digest",
]

Kind = Literal["W", "WE"]
#: Multiplier time constant / receiving neuron's time constant (paper section 2: "an order of
#: magnitude" smaller).
DEFAULT_TAU_RATIO = 0.1

_LABEL = re.compile(r"^\s*(WE|W)\s*\[\s*(\d+)\s*,\s*(\d+)\s*\]\s*$")


@dataclasses.dataclass(frozen=True, order=True)
class Connection:
    """One connection of a CTRNN, 0-based.

    Attributes:
        kind: ``"W"`` for a recurrent connection ``W[i, j]`` (neuron j -> neuron i) or ``"WE"`` for
            an input connection ``WE[i, j]`` (external input j -> neuron i).
        i: receiving neuron.
        j: source neuron (``W``) or source input (``WE``).
    """

    kind: Kind
    i: int
    j: int

    def __post_init__(self) -> None:
        if self.kind not in ("W", "WE"):
            raise MbnInputError(f"connection kind must be 'W' or 'WE', got {self.kind!r}")
        if self.i < 0 or self.j < 0:
            raise MbnInputError(f"connection {self.kind}[{self.i},{self.j}]: negative index")

    def __str__(self) -> str:
        return f"{self.kind}[{self.i},{self.j}]"

    @property
    def paper_name(self) -> str:
        """The paper's 1-based name, e.g. ``W_23`` for ``W[1,2]``."""
        return f"{self.kind}_{self.i + 1}{self.j + 1}"

    @classmethod
    def parse(cls, text: str) -> Connection:
        """Parse ``"W[i,j]"`` or ``"WE[i,k]"`` (0-based)."""
        match = _LABEL.match(text)
        if not match:
            raise MbnInputError(f"connection: expected 'W[i,j]' or 'WE[i,k]', got {text!r}")
        kind: Kind = "WE" if match[1] == "WE" else "W"
        return cls(kind, int(match[2]), int(match[3]))

    def value(self, net: CTRNN) -> Array:
        """The weight of this connection in ``net``."""
        self.check(net)
        return (net.W if self.kind == "W" else net.WE)[..., self.i, self.j]

    def check(self, net: CTRNN) -> None:
        """Raise :class:`MbnInputError` if the connection does not exist in ``net``."""
        limit = net.num_neurons if self.kind == "W" else net.num_inputs
        if self.i >= net.num_neurons or self.j >= limit:
            raise MbnInputError(
                f"connection {self}: out of range for a network with {net.num_neurons} neurons "
                f"and {net.num_inputs} inputs"
            )


@dataclasses.dataclass(frozen=True)
class Programmable:
    """A connection to make programmable, with the range ``(lower, upper)`` its weight may take."""

    connection: Connection
    lower: float
    upper: float

    def __post_init__(self) -> None:
        if not (np.isfinite(self.lower) and np.isfinite(self.upper)):
            raise MbnInputError(f"{self.connection}: bounds must be finite")
        if not self.lower < self.upper:
            raise MbnInputError(f"{self.connection}: min {self.lower} must be < max {self.upper}")


def weights_digest(
    net: Sequence[ArrayLike], lower: ArrayLike, upper: ArrayLike, connections: Sequence[object]
) -> str:
    """sha256 of an interpreter's fixed weights, :meth:`Interpreter.digest`: ``net`` its
    network's ``(W, WE, tau, bias, gain)`` (``tau``, ``bias`` and ``gain`` of shape ``(n,)``),
    each array hashed as float64 with its shape, then the connections' names. A file's values
    give the digest of the interpreter that wrote them, in float32 or float64 (a float32 value
    is written exactly)."""
    import hashlib

    h = hashlib.sha256()
    for a in (*net, lower, upper):
        arr = np.ascontiguousarray(np.asarray(a, dtype=np.float64))
        h.update(str(arr.shape).encode())
        h.update(arr.tobytes())
    h.update(",".join(map(str, connections)).encode())
    return h.hexdigest()


def all_connections(net: CTRNN, *, bound: float = 10.0) -> list[Programmable]:
    """Every ``W`` and ``WE`` connection of ``net`` with bounds ``(-bound, bound)``."""
    conns = [Connection("W", i, j) for i in range(net.num_neurons) for j in range(net.num_neurons)]
    conns += [Connection("WE", i, k) for i in range(net.num_neurons) for k in range(net.num_inputs)]
    return [Programmable(c, -bound, bound) for c in conns]


def differing_connections(
    a: CTRNN, b: CTRNN, *, margin: float = 0.1, atol: float = 0.0
) -> list[Programmable]:
    """The connections whose weights differ between two networks of the same shape.

    Bounds are ``[min(a, b) - margin * span, max(a, b) + margin * span]`` with
    ``span = |a - b|``, so that both programs lie strictly inside (0, 1), away from the edges of the
    multiplier's input range. Connections that differ by at most ``atol`` count as equal.
    Ordered ``W`` first, then ``WE``, each row-major.
    """
    if a.W.shape != b.W.shape or a.WE.shape != b.WE.shape:
        raise MbnInputError(
            f"networks differ in shape: W {a.W.shape} vs {b.W.shape}, "
            f"WE {a.WE.shape} vs {b.WE.shape}"
        )
    if margin < 0:
        raise MbnInputError(f"margin: must be >= 0, got {margin}")
    out = []
    pairs: tuple[tuple[Kind, Array, Array], ...] = (("W", a.W, b.W), ("WE", a.WE, b.WE))
    for kind, ma, mb in pairs:
        ma_, mb_ = np.asarray(ma, np.float64), np.asarray(mb, np.float64)
        for i, j in zip(*np.nonzero(np.abs(ma_ - mb_) > atol), strict=True):
            lo, hi = sorted((ma_[i, j], mb_[i, j]))
            span = hi - lo
            out.append(
                Programmable(
                    Connection(kind, int(i), int(j)), lo - margin * span, hi + margin * span
                )
            )
    return out


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Interpreter:
    """A fixed-weight interpreter network and its program codec.

    Attributes:
        net: the whole fixed-weight CTRNN: the ``num_original`` original neurons first, then one
            block of ``mul_size`` neurons per programmable connection; its inputs are the
            ``num_data_inputs`` original inputs followed by one program input per connection.
        lower, upper: bounds ``(min, max)`` of each programmable connection, shape ``(K,)``.
        connections: the programmable connections, in program order.
        num_original: neurons of the original network.
        num_data_inputs: inputs of the original network.
        mul_size: neurons per multiplier block.
        mul_output: index of the output neuron inside a multiplier block.
    """

    net: CTRNN
    lower: Array
    upper: Array
    connections: tuple[Connection, ...] = dataclasses.field(metadata={"static": True})
    num_original: int = dataclasses.field(metadata={"static": True})
    num_data_inputs: int = dataclasses.field(metadata={"static": True})
    mul_size: int = dataclasses.field(metadata={"static": True})
    mul_output: int = dataclasses.field(metadata={"static": True})

    @property
    def num_programs(self) -> int:
        """Number of program inputs ``K`` (= programmable connections)."""
        return len(self.connections)

    @property
    def num_neurons(self) -> int:
        """Neurons of the whole interpreter, ``num_original + K * mul_size``."""
        return self.net.num_neurons

    def digest(self) -> str:
        """sha256 of the interpreter's fixed weights (W, WE, tau, bias, gain, bounds, and its
        connections): a run records it to check the interpreter was not changed
        (:func:`weights_digest`)."""
        return weights_digest(
            [getattr(self.net, f) for f in ("W", "WE", "tau", "bias", "gain")],
            self.lower,
            self.upper,
            self.connections,
        )

    def blocks(self) -> BlockNet:
        """The same network by its structure (:mod:`mbn.networks.structured`)."""
        return from_interpreter(
            self.net, self.num_original, self.num_data_inputs, self.mul_size, self.mul_output
        )

    def mul_block(self, c: int) -> slice:
        """Neuron indices of the multiplier of connection ``c``."""
        start = self.num_original + c * self.mul_size
        return slice(start, start + self.mul_size)

    def encode(self, weights: ArrayLike) -> Array:
        """Program ``p = (w - min) / (max - min)`` (eq. 2) for weights ``(..., K)``, in [0, 1].

        Raises:
            MbnInputError: a weight outside its bounds (its code would leave [0, 1]).
        """
        w = jnp.asarray(weights, dtype=self.net.dtype)
        if w.shape[-1:] != (self.num_programs,):
            raise MbnInputError(
                f"weights: expected shape (..., {self.num_programs}), got {w.shape}"
            )
        lo, hi = np.asarray(self.lower), np.asarray(self.upper)
        w_np = np.asarray(w)
        bad = (w_np < lo) | (w_np > hi)
        if np.any(bad):
            c = int(np.argwhere(bad)[0][-1])
            raise MbnInputError(
                f"weights: {self.connections[c]} = {w_np[..., c].ravel()[0]:g} is outside its "
                f"bounds [{lo[c]:g}, {hi[c]:g}]"
            )
        # within its bounds a weight's code is in [0, 1]; the division may round past an end
        # by an ulp where XLA computes it as a product by the reciprocal (on a GPU), and a
        # program is checked against [0, 1] exactly (``check_program``, controller files)
        return jnp.clip((w - self.lower) / (self.upper - self.lower), 0.0, 1.0)

    def decode(self, program: ArrayLike) -> Array:
        """Weights ``min + p * (max - min)`` for a program ``(..., K)`` in [0, 1]."""
        p = check_program(self, program)
        return self.lower + p * (self.upper - self.lower)

    def program_of(self, net: CTRNN) -> Array:
        """The program that makes the interpreter emulate ``net`` (same shape as the original)."""
        if net.W.shape[-1] != self.num_original or net.WE.shape[-1] != self.num_data_inputs:
            raise MbnInputError(
                f"network: expected {self.num_original} neurons and {self.num_data_inputs} inputs, "
                f"got {net.num_neurons} and {net.num_inputs}"
            )
        return self.encode(jnp.stack([c.value(net) for c in self.connections], axis=-1))

    def initial_state(self, y0: ArrayLike) -> Array:
        """Interpreter state from original potentials ``(..., num_original)``, multipliers at 0."""
        y0 = jnp.asarray(y0, dtype=self.net.dtype)
        pad = jnp.zeros((*y0.shape[:-1], self.num_neurons - self.num_original), y0.dtype)
        return jnp.concatenate([y0, pad], axis=-1)

    def inputs(self, data: ArrayLike, program: ArrayLike) -> Array:
        """Interpreter inputs: data ``(..., m)`` and program ``(..., K)``, broadcast and joined."""
        data = jnp.asarray(data, dtype=self.net.dtype)
        program = jnp.asarray(program, dtype=self.net.dtype)
        shape = jnp.broadcast_shapes(data.shape[:-1], program.shape[:-1])
        return jnp.concatenate(
            [
                jnp.broadcast_to(data, (*shape, data.shape[-1])),
                jnp.broadcast_to(program, (*shape, program.shape[-1])),
            ],
            axis=-1,
        )


def check_program(interp: Interpreter, program: ArrayLike) -> Array:
    """Validate a program ``(..., K)``: right length, finite, inside [0, 1]."""
    p = jnp.asarray(program, dtype=interp.net.dtype)
    if p.shape[-1:] != (interp.num_programs,):
        raise MbnInputError(f"program: expected shape (..., {interp.num_programs}), got {p.shape}")
    if not isinstance(p, jax.core.Tracer):
        p_np = np.asarray(p)
        if not np.all(np.isfinite(p_np)) or np.any((p_np < 0) | (p_np > 1)):
            raise MbnInputError(
                f"program: values must be in [0, 1], got min {np.nanmin(p_np):g} "
                f"max {np.nanmax(p_np):g}"
            )
    return p


def check_data_inputs(interp: Interpreter, data: ArrayLike) -> None:
    """Raise if an input that feeds a programmable ``WE`` connection leaves [0, 1]."""
    cols = sorted({c.j for c in interp.connections if c.kind == "WE"})
    if not cols or isinstance(data, jax.core.Tracer):
        return
    d = np.asarray(data)[..., cols]
    if np.any((d < 0) | (d > 1)) or not np.all(np.isfinite(d)):
        raise MbnInputError(
            f"inputs: input(s) {cols} feed programmable WE connections and must stay in [0, 1] "
            f"(a multiplier multiplies numbers in (0, 1)); got min {np.nanmin(d):g} "
            f"max {np.nanmax(d):g}"
        )


def build_interpreter(
    net: CTRNN,
    programmable: Sequence[Programmable],
    multiplier: Multiplier,
    *,
    tau_ratio: float = DEFAULT_TAU_RATIO,
    mul_tau: float | None = None,
) -> Interpreter:
    """Build the fixed-weight interpreter of ``net`` (paper section 2, Fig. 1, eq. 2).

    Args:
        net: the original network (unbatched), ``n`` neurons and ``m`` inputs.
        programmable: the connections to replace, each with its bounds; any subset of the
            ``n*n`` recurrent and ``n*m`` input connections, no duplicates.
        multiplier: the multiplier sub-network (its time constants are relative).
        tau_ratio: multiplier time constant as a fraction of the receiving neuron's tau
            (paper: about one order of magnitude smaller, so 0.1).
        mul_tau: an absolute multiplier time constant in seconds instead of ``tau_ratio``.

    Returns:
        The :class:`Interpreter`: ``n + K * multiplier.num_neurons`` neurons, ``m + K`` inputs.
    """
    if net.W.ndim != 2:
        raise MbnInputError(f"network: expected an unbatched network, got W shape {net.W.shape}")
    if not programmable:
        raise MbnInputError("programmable: choose at least one connection")
    conns = [p.connection for p in programmable]
    if len(set(conns)) != len(conns):
        raise MbnInputError("programmable: a connection is listed twice")
    for conn in conns:
        conn.check(net)
    if mul_tau is None and not tau_ratio > 0:
        raise MbnInputError(f"tau_ratio: must be > 0, got {tau_ratio}")
    if mul_tau is not None and not mul_tau > 0:
        raise MbnInputError(f"mul_tau: must be > 0, got {mul_tau}")
    if multiplier.net.W.ndim != 2:
        raise MbnInputError("multiplier: expected an unbatched multiplier")

    n, m, K = net.num_neurons, net.num_inputs, len(conns)
    q = multiplier.num_neurons
    total = n + K * q
    W = np.zeros((total, total))
    WE = np.zeros((total, m + K))
    tau = np.zeros(total)
    bias = np.zeros(total)
    gain = np.ones(total)
    W[:n, :n] = np.asarray(net.W, np.float64)
    WE[:n, :m] = np.asarray(net.WE, np.float64)
    tau[:n] = np.asarray(net.tau, np.float64)
    bias[:n] = np.asarray(net.bias, np.float64)
    gain[:n] = np.asarray(net.gain, np.float64)
    mW = np.asarray(multiplier.net.W, np.float64)
    mWE = np.asarray(multiplier.net.WE, np.float64)
    for c, prog in enumerate(programmable):
        conn = prog.connection
        block = slice(n + c * q, n + (c + 1) * q)
        # direct connection keeps the weight `min` (eq. 2)
        if conn.kind == "W":
            W[conn.i, conn.j] = prog.lower
            W[block, conn.j] = mWE[:, 0]  # x1 <- firing rate of the source neuron
        else:
            WE[conn.i, conn.j] = prog.lower
            WE[block, conn.j] = mWE[:, 0]  # x1 <- the external input
        WE[block, m + c] = mWE[:, 1]  # x2 <- program input c
        W[block, block] = mW
        W[conn.i, block.start + multiplier.output] = prog.upper - prog.lower
        scale = mul_tau if mul_tau is not None else tau_ratio * tau[conn.i]
        tau[block] = np.asarray(multiplier.net.tau, np.float64) * scale
        bias[block] = np.asarray(multiplier.net.bias, np.float64)
        gain[block] = np.asarray(multiplier.net.gain, np.float64)
    dtype = net.W.dtype
    return Interpreter(
        net=make_ctrnn(W, WE, tau, bias=bias, gain=gain, dtype=dtype, name="interpreter"),
        lower=jnp.asarray([p.lower for p in programmable], dtype),
        upper=jnp.asarray([p.upper for p in programmable], dtype),
        connections=tuple(conns),
        num_original=n,
        num_data_inputs=m,
        mul_size=q,
        mul_output=multiplier.output,
    )


def _original_part(interp: Interpreter) -> CTRNN:
    """The original neurons of the interpreter with their direct (``min``) connections."""
    n, m = interp.num_original, interp.num_data_inputs
    net = interp.net
    return CTRNN(
        W=net.W[:n, :n], WE=net.WE[:n, :m], tau=net.tau[:n], bias=net.bias[:n], gain=net.gain[:n]
    )


def _exact_field(interp: Interpreter, y: Array, u: Array) -> Array:
    """Original neurons of the interpreter with every multiplier replaced by the exact product.

    Uses the interpreter's own wiring (direct ``min`` weights, ``max - min`` output weights) so
    that construction errors show up; only the multiplication itself is exact.
    """
    m = interp.num_data_inputs
    net = interp.net
    sub = _original_part(interp)
    data, program = u[..., :m], u[..., m:]
    dydt = vector_field(sub, y, data)
    r = firing_rate(sub, y)
    for c, conn in enumerate(interp.connections):
        source = r[..., conn.j] if conn.kind == "W" else data[..., conn.j]
        scale = net.W[conn.i, interp.mul_block(c).start + interp.mul_output]
        dydt = dydt.at[..., conn.i].add(scale * source * program[..., c] / net.tau[conn.i])
    return dydt


def _settle_multipliers(
    interp: Interpreter,
    y0: Array,
    u0: Array,
    dt: float | Array,
    method: str,
    blocks: BlockNet | None = None,
) -> Array:
    """Let the multipliers reach their fixed point for the initial inputs, neurons held still.

    A multiplier started at rest outputs a wrong product for a few tau_m; in a network with
    weights of hundreds this transient can tip the network into another attractor. The settled
    start is what the interpreter would show had it been running with these inputs for a while.
    """
    frozen = jnp.arange(interp.num_neurons) < interp.num_original
    mul_tau = jnp.min(jnp.where(frozen, jnp.inf, interp.net.tau))

    def field(y: Array, u: Array) -> Array:
        f = vector_field(interp.net, y, u) if blocks is None else block_field(blocks, y, u)
        return jnp.where(frozen, 0.0, f)

    # 2 T (T = 10 tau_m): the settling time the multipliers are checked against
    num = jnp.ceil(2 * 10 * mul_tau / dt).astype(int)
    one_step = integrator(method)
    return jax.lax.fori_loop(0, num, lambda _, y: one_step(lambda z: field(z, u0), y, dt), y0)


@functools.partial(jax.jit, static_argnames=("method", "substeps", "exact"))
def _run(
    interp: Interpreter,
    y0: Array,
    inputs: Array,
    dt: float | Array,
    method: str,
    substeps: int,
    exact: bool,
    blocks: BlockNet | None = None,
) -> Array:
    if blocks is not None:
        if exact:
            field = functools.partial(block_exact_field, blocks)
        else:
            field = functools.partial(block_field, blocks)
            y0 = _settle_multipliers(interp, y0, inputs[0], dt, method, blocks)
    elif exact:
        field = functools.partial(_exact_field, interp)
        y0 = y0[..., : interp.num_original]
    else:
        field = functools.partial(vector_field, interp.net)
        y0 = _settle_multipliers(interp, y0, inputs[0], dt, method)
    _, ys = integrate(field, y0, inputs, dt, method=method, substeps=substeps, record=True)
    assert ys is not None
    return firing_rate(_original_part(interp), ys[..., : interp.num_original])


def run(
    interp: Interpreter,
    y0: ArrayLike,
    data: ArrayLike,
    program: ArrayLike,
    dt: float,
    *,
    method: Method = "rk4",
    substeps: int = 1,
    exact: bool = False,
    simulation: str = "dense",
) -> Array:
    """Run the interpreter over piecewise-constant data inputs with a program.

    Args:
        interp: the interpreter.
        y0: initial potentials of the original neurons ``(..., n)``; the multipliers start at
            their fixed point for the first inputs (settled with the neurons held at ``y0``).
        data: data inputs ``(num_steps, ..., m)``.
        program: program ``(K,)``, ``(..., K)`` or time-varying ``(num_steps, ..., K)``, in [0, 1].
        dt: step in seconds (see :func:`mbn.networks.ctrnn.check_dt` for stability).
        method: 'euler' or 'rk4'.
        substeps: integrator steps per input step.
        exact: replace every multiplier by the exact product.
        simulation: ``"dense"`` (one CTRNN of all the neurons) or ``"blocks"`` (by its
            structure, :mod:`mbn.networks.structured`; the same network).

    Returns:
        Firing rates of the original neurons after each step, ``(num_steps, ..., n)``.
    """
    data = jnp.asarray(data, dtype=interp.net.dtype)
    check_data_inputs(interp, data)
    program = check_program(interp, program)
    inputs = interp.inputs(data, program)
    if simulation not in ("dense", "blocks"):
        raise MbnInputError(f"simulation: expected dense or blocks, got {simulation!r}")
    blocks = interp.blocks() if simulation == "blocks" else None
    return _run(interp, interp.initial_state(y0), inputs, dt, method, substeps, exact, blocks)


@functools.partial(jax.jit, static_argnames=("method", "substeps"))
def _run_network(
    net: CTRNN, y0: Array, data: Array, dt: float | Array, method: str, substeps: int
) -> Array:
    _, ys = integrate(
        functools.partial(vector_field, net), y0, data, dt, method=method, substeps=substeps
    )
    assert ys is not None
    return firing_rate(net, ys)


def run_network(
    net: CTRNN,
    y0: ArrayLike,
    data: ArrayLike,
    dt: float,
    *,
    method: Method = "rk4",
    substeps: int = 1,
) -> Array:
    """Firing rates of a plain network after each step (the reference an interpreter emulates)."""
    data = jnp.asarray(data, dtype=net.dtype)
    return _run_network(net, jnp.asarray(y0, net.dtype), data, dt, method, substeps)
