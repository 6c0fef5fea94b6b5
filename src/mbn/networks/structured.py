"""An interpreter simulated by its structure: the original neurons beside a batch of small
multiplier CTRNNs, one per programmable connection.

:func:`mbn.networks.programmable.build_interpreter` builds the interpreter as one dense CTRNN of
``n + K q`` neurons (``K`` multipliers of ``q`` neurons). Most of its ``(n + K q)^2`` weights are
zero: a multiplier's neurons are connected among themselves (the same ``q x q`` matrix in every
block), to the one neuron or input it reads (``x1``), to its program input (``x2``), and its
output neuron to the one neuron it feeds. :class:`BlockNet` keeps exactly those blocks, read
from the dense network, so that one step costs ``O(n^2 + K q^2)`` instead of ``O((n + K q)^2)``:
linear in the number of programmable connections. It is the same network: its vector field
equals the dense one's (:func:`block_field`; tested to round-off in float64), on the same state
layout (the original potentials, then block after block).

A controller runs it through :func:`block_euler_steps`, which — like
:func:`mbn.networks.ctrnn.euler_steps` — integrates a batch of robots sharing one interpreter
neuron-major, the batch along the fast axis.
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from mbn.errors import MbnInputError
from mbn.networks.ctrnn import CTRNN, make_ctrnn

__all__ = [
    "CHUNK",
    "BlockNet",
    "block_euler_steps",
    "block_exact_field",
    "block_field",
    "block_rates",
    "from_interpreter",
]


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class BlockNet:
    """The interpreter's blocks (``n`` original neurons, ``m`` data inputs, ``K`` multipliers of
    ``q`` neurons; inputs: the data, then one program value per multiplier).

    Attributes:
        core: the original neurons with their direct connections (weights ``min`` where a
            connection is programmable), ``n`` neurons, ``m`` inputs.
        mul_W: each multiplier's recurrent weights, ``(K, q, q)``.
        x1_weight: weights of a multiplier's ``x1`` input into its neurons, ``(K, q)``.
        x1_neuron: the original neuron whose rate is ``x1`` (a recurrent connection), else -1,
            ``(K,)``.
        x1_input: the data input that is ``x1`` (input connection), else -1, ``(K,)``.
        x2_weight: weights of a multiplier's program input into its neurons, ``(K, q)``.
        mul_tau, mul_bias, mul_gain: the multiplier neurons' parameters, ``(K, q)``.
        out_weight: weight of each multiplier's output neuron into its target, ``(K,)``
            (``max - min``).
        target: the original neuron a multiplier feeds, ``(K,)``.
        output: index of the output neuron inside a block.
    """

    core: CTRNN
    mul_W: Array
    x1_weight: Array
    x2_weight: Array
    mul_tau: Array
    mul_bias: Array
    mul_gain: Array
    out_weight: Array
    x1_neuron: tuple[int, ...] = dataclasses.field(metadata={"static": True})
    x1_input: tuple[int, ...] = dataclasses.field(metadata={"static": True})
    target: tuple[int, ...] = dataclasses.field(metadata={"static": True})
    output: int = dataclasses.field(metadata={"static": True})

    @property
    def num_original(self) -> int:
        return self.core.num_neurons

    @property
    def num_multipliers(self) -> int:
        return int(self.mul_W.shape[-3])

    @property
    def mul_size(self) -> int:
        return int(self.mul_W.shape[-1])

    @property
    def num_neurons(self) -> int:
        """Neurons of the whole interpreter, ``n + K q`` (the length of its state)."""
        return self.num_original + self.num_multipliers * self.mul_size

    @property
    def num_inputs(self) -> int:
        """Data inputs and program inputs, ``m + K``."""
        return self.core.num_inputs + self.num_multipliers

    @property
    def dtype(self) -> jnp.dtype:
        return self.core.dtype

    def routing(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One-hot matrices: ``x1`` from the neurons ``(K, n)``, from the data ``(K, m)``, and
        the multipliers' outputs into the neurons ``(n, K)``."""
        n, m, K = self.num_original, self.core.num_inputs, self.num_multipliers
        from_rate, from_data, into = np.zeros((K, n)), np.zeros((K, m)), np.zeros((n, K))
        for c in range(K):
            if self.x1_neuron[c] >= 0:
                from_rate[c, self.x1_neuron[c]] = 1.0
            else:
                from_data[c, self.x1_input[c]] = 1.0
            into[self.target[c], c] = 1.0
        return from_rate, from_data, into


def from_interpreter(
    net: CTRNN, num_original: int, num_data_inputs: int, mul_size: int, mul_output: int
) -> BlockNet:
    """The blocks of a dense interpreter network (``build_interpreter``'s layout), checked:
    every weight outside the blocks must be zero, so that the two are one network.

    Raises:
        MbnInputError: the dense network has a connection the block layout cannot hold.
    """
    W, WE = np.asarray(net.W, np.float64), np.asarray(net.WE, np.float64)
    n, m, q = num_original, num_data_inputs, mul_size
    if W.ndim != 2:
        raise MbnInputError(f"interpreter: expected an unbatched network, got W {W.shape}")
    total = W.shape[0]
    K = (total - n) // q
    if n + K * q != total or WE.shape != (total, m + K):
        raise MbnInputError(
            f"interpreter: {total} neurons and {WE.shape[1]} inputs do not make {n} neurons, "
            f"{m} inputs and blocks of {q}"
        )
    accounted_W = np.zeros_like(W, dtype=bool)
    accounted_WE = np.zeros_like(WE, dtype=bool)
    accounted_W[:n, :n] = True
    accounted_WE[:n, :m] = True
    mul_W, x1_w, x2_w, out_w = [], [], [], []
    x1_neuron, x1_input, target = [], [], []
    for c in range(K):
        b = slice(n + c * q, n + (c + 1) * q)
        mul_W.append(W[b, b])
        accounted_W[b, b] = True
        x2_w.append(WE[b, m + c])
        accounted_WE[b, m + c] = True
        src_n = np.nonzero(np.any(W[b, :n] != 0, axis=0))[0]
        src_u = np.nonzero(np.any(WE[b, :m] != 0, axis=0))[0]
        if len(src_n) + len(src_u) != 1:
            raise MbnInputError(
                f"interpreter: multiplier {c} reads {len(src_n) + len(src_u)} sources, not 1"
            )
        if len(src_n):
            j = int(src_n[0])
            x1_w.append(W[b, j])
            accounted_W[b, j] = True
            x1_neuron.append(j)
            x1_input.append(-1)
        else:
            j = int(src_u[0])
            x1_w.append(WE[b, j])
            accounted_WE[b, j] = True
            x1_neuron.append(-1)
            x1_input.append(j)
        into = np.nonzero(W[:n, b.start + mul_output])[0]
        if len(into) != 1:
            raise MbnInputError(f"interpreter: multiplier {c} feeds {len(into)} neurons, not 1")
        target.append(int(into[0]))
        out_w.append(W[into[0], b.start + mul_output])
        accounted_W[into[0], b.start + mul_output] = True
    if np.any(W[~accounted_W] != 0) or np.any(WE[~accounted_WE] != 0):
        raise MbnInputError("interpreter: it has connections outside its multiplier blocks")
    tau, bias, gain = (np.asarray(a, np.float64) for a in (net.tau, net.bias, net.gain))
    blocks = lambda a: a[n:].reshape(K, q)  # noqa: E731
    dtype = net.dtype
    core = make_ctrnn(W[:n, :n], WE[:n, :m], tau[:n], bias=bias[:n], gain=gain[:n], dtype=dtype)
    arr = lambda a: jnp.asarray(np.asarray(a), dtype)  # noqa: E731
    return BlockNet(
        core=core,
        mul_W=arr(mul_W),
        x1_weight=arr(x1_w),
        x2_weight=arr(x2_w),
        mul_tau=arr(blocks(tau)),
        mul_bias=arr(blocks(bias)),
        mul_gain=arr(blocks(gain)),
        out_weight=arr(out_w),
        x1_neuron=tuple(x1_neuron),
        x1_input=tuple(x1_input),
        target=tuple(target),
        output=mul_output,
    )


def _x1(net: BlockNet, r0: Array, data: Array) -> Array:
    """Each multiplier's ``x1`` ``(..., K)`` from the rates ``(..., n)`` and data ``(..., m)``."""
    cols = [
        r0[..., j] if j >= 0 else data[..., k]
        for j, k in zip(net.x1_neuron, net.x1_input, strict=True)
    ]
    return jnp.stack(cols, axis=-1)


def _into(net: BlockNet, out: Array, axis: int = -1) -> Array:
    """The multipliers' weighted outputs (``K`` along ``axis``) summed into their targets
    (``n`` along ``axis``)."""
    rows = []
    for i in range(net.num_original):
        terms = [jnp.take(out, c, axis) for c in range(net.num_multipliers) if net.target[c] == i]
        rows.append(sum(terms[1:], terms[0]) if terms else jnp.zeros_like(jnp.take(out, 0, axis)))
    return jnp.stack(rows, axis=axis)


def block_field(net: BlockNet, y: ArrayLike, inputs: ArrayLike) -> Array:
    """``dy/dt`` of the interpreter (eq. 1) on the dense layout ``y (..., n + K q)``, inputs
    ``(..., m + K)`` (data, then program): the dense network's vector field, block by block."""
    y, u = jnp.asarray(y), jnp.asarray(inputs)
    n, m, K, q = net.num_original, net.core.num_inputs, net.num_multipliers, net.mul_size
    y0, ym = y[..., :n], y[..., n:].reshape(*y.shape[:-1], K, q)
    data, program = u[..., :m], u[..., m:]
    c = net.core
    r0 = jax.nn.sigmoid(c.gain * (y0 + c.bias))
    rm = jax.nn.sigmoid(net.mul_gain * (ym + net.mul_bias))
    out = net.out_weight * rm[..., net.output]
    d0 = (
        jnp.einsum("...ij,...j->...i", c.W, r0)
        + jnp.einsum("...ik,...k->...i", c.WE, data)
        + _into(net, out)
        - y0
    ) / c.tau
    drive = (
        jnp.einsum("...ckl,...cl->...ck", net.mul_W, rm)
        + net.x1_weight * _x1(net, r0, data)[..., None]
        + net.x2_weight * program[..., None]
    )
    dm = (drive - ym) / net.mul_tau
    return jnp.concatenate([d0, dm.reshape(*ym.shape[:-2], K * q)], axis=-1)


def block_exact_field(net: BlockNet, y: ArrayLike, inputs: ArrayLike) -> Array:
    """:func:`block_field` with every multiplier replaced by the exact product ``x1 p`` (the
    multipliers' potentials stay as they are): construction errors (wiring, codec) apart from
    the multipliers' approximation errors, by the structured path."""
    y, u = jnp.asarray(y), jnp.asarray(inputs)
    n, m = net.num_original, net.core.num_inputs
    y0 = y[..., :n]
    data, program = u[..., :m], u[..., m:]
    c = net.core
    r0 = jax.nn.sigmoid(c.gain * (y0 + c.bias))
    product = net.out_weight * _x1(net, r0, data) * program
    d0 = (
        jnp.einsum("...ij,...j->...i", c.W, r0)
        + jnp.einsum("...ik,...k->...i", c.WE, data)
        + _into(net, product)
        - y0
    ) / c.tau
    return jnp.concatenate([d0, jnp.zeros_like(y[..., n:])], axis=-1)


def block_rates(net: BlockNet, y: ArrayLike) -> Array:
    """Firing rates of the original neurons ``(..., n)`` (the motor neurons are among them)."""
    y = jnp.asarray(y)
    c = net.core
    return jax.nn.sigmoid(c.gain * (y[..., : net.num_original] + c.bias))


def block_euler_steps(
    net: BlockNet, y: ArrayLike, inputs: ArrayLike, dt: float, steps: int
) -> Array:
    """``steps`` forward-Euler steps of ``dt`` seconds with the inputs held, for one state
    ``y (n + K q,)``; mapped by :func:`jax.vmap` over a batch of states with ``net`` held, the
    batch is integrated neuron-major (see :func:`mbn.networks.ctrnn.euler_steps`)."""
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise MbnInputError(f"steps must be an integer >= 1, got {steps!r}")
    return _block_steps(float(dt), steps)(net, jnp.asarray(y), jnp.asarray(inputs))


#: Robots integrated together by :func:`block_euler_steps` on a batch: the batch is cut into
#: chunks of this many (when it divides), so that one chunk's states stay in the cache over the
#: sub-steps (``docs/speed.md``).
CHUNK = 512


@functools.lru_cache(maxsize=64)
def _block_steps(dt: float, steps: int):  # type: ignore[no-untyped-def]
    def plain(net: BlockNet, y: Array, inputs: Array) -> Array:
        for _ in range(steps):
            y = y + dt * block_field(net, y, inputs)
        return y

    run = jax.custom_batching.custom_vmap(plain)

    @run.def_vmap
    def batched(axis_size, in_batched, net, y, inputs):  # type: ignore[no-untyped-def]
        net_batched, y_batched, u_batched = in_batched
        if any(jax.tree.leaves(net_batched)) or net.mul_W.ndim != 3 or y.ndim != 2:
            axes = (
                jax.tree.map(lambda b: 0 if b else None, net_batched),
                0 if y_batched else None,
                0 if u_batched else None,
            )
            return jax.vmap(plain, in_axes=axes, axis_size=axis_size)(net, y, inputs), True
        y = y if y_batched else jnp.broadcast_to(y, (axis_size, y.shape[-1]))
        u = inputs if u_batched else jnp.broadcast_to(inputs, (axis_size, inputs.shape[-1]))
        B = axis_size
        if B > CHUNK and B % CHUNK == 0:
            parts = B // CHUNK
            out = jax.lax.map(
                lambda a: _neuron_major(net, a[0].T, a[1].T, dt, steps).T,
                (y.reshape(parts, CHUNK, -1), u.reshape(parts, CHUNK, -1)),
            )
            return out.reshape(B, -1), True
        return _neuron_major(net, y.T, u.T, dt, steps).T, True

    return run


def _neuron_major(net: BlockNet, yt: Array, u: Array, dt: float, steps: int) -> Array:
    """``steps`` Euler steps of a batch laid out neuron-major: potentials ``yt (n + K q, B)``,
    inputs ``u (m + K, B)``. Euler's step is folded into the weights
    (``y <- (1 - h/tau) y + (h/tau) drive``), the held inputs' part of the drive computed once,
    and the logistic written as ``(1 + tanh(z / 2)) / 2`` with its halves folded into the weights
    (the same function; about a fifth cheaper on a CPU)."""
    n, m, K, q = net.num_original, net.core.num_inputs, net.num_multipliers, net.mul_size
    c = net.core
    data, program = u[:m], u[m:]
    y0, ym = yt[:n], yt[n:].reshape(K, q, -1)
    k0 = (dt / c.tau)[:, None]  # (n, 1)
    km = (dt / net.mul_tau)[:, :, None]  # (K, q, 1)
    # rates r = (1 + t) / 2 with t = tanh(g (y + b) / 2): W r = W t / 2 + (sum of W) / 2
    W0 = 0.5 * k0 * c.W
    fixed0 = k0 * (c.WE @ data) + 0.5 * k0 * jnp.sum(c.W, axis=1)[:, None]
    Wm = 0.5 * km[..., None] * net.mul_W[:, :, :, None]  # (K, q, q, 1)
    fixedm = (
        km * (net.x2_weight[:, :, None] * program[:, None, :])
        + 0.5 * km * jnp.sum(net.mul_W, axis=2)[:, :, None]
    )
    target = np.asarray(net.target)
    k_out = (dt / c.tau)[target] * net.out_weight  # (K,)
    # a multiplier's output r = (1 + t) / 2 into its target: the constant half is fixed
    fixed0 = fixed0 + _into(net, 0.5 * k_out[:, None] * jnp.ones_like(data[:1]), axis=0)
    out_w = 0.5 * k_out[:, None]
    x1w = km * net.x1_weight[:, :, None]
    g0, gb0 = 0.5 * c.gain[:, None], 0.5 * (c.gain * c.bias)[:, None]
    gm = 0.5 * net.mul_gain[:, :, None]
    gbm = 0.5 * (net.mul_gain * net.mul_bias)[:, :, None]
    keep0, keepm = 1.0 - k0, 1.0 - km

    def one(_: int, carry: tuple[Array, Array]) -> tuple[Array, Array]:
        y0, ym = carry
        t0 = jnp.tanh(g0 * y0 + gb0)  # (n, B)
        tm = jnp.tanh(gm * ym + gbm)  # (K, q, B)
        # x1: a neuron's rate (1 + t) / 2, or a data input
        x1 = jnp.stack(
            [
                0.5 * (1.0 + t0[j]) if j >= 0 else jnp.broadcast_to(data[k], t0[0].shape)
                for j, k in zip(net.x1_neuron, net.x1_input, strict=True)
            ]
        )  # (K, B)
        into = _into(net, out_w * tm[:, net.output], axis=0)
        y0 = keep0 * y0 + _cols(W0, t0) + fixed0 + into
        mix = Wm[:, :, 0] * tm[:, None, 0]
        for l_ in range(1, q):
            mix = mix + Wm[:, :, l_] * tm[:, None, l_]
        ym = keepm * ym + mix + x1w * x1[:, None, :] + fixedm
        return y0, ym

    y0, ym = jax.lax.fori_loop(0, steps, one, (y0, ym))
    return jnp.concatenate([y0, ym.reshape(K * q, -1)])


def _cols(a: Array, x: Array) -> Array:
    """``a (n, k) @ x (k, B)`` as ``k`` broadcasts (small ``k``), which XLA fuses."""
    out = a[:, 0, None] * x[None, 0]
    for j in range(1, a.shape[1]):
        out = out + a[:, j, None] * x[None, j]
    return out
