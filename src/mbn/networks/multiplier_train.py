"""Training the multiplier CTRNN (paper section 2.1) by backpropagation through time.

Many random restarts are trained at once, batched in one array (BPTT through a ``lax.scan``, with
a hand-written adjoint for Euler); the best restart by validation that also passes the fixed-point
check is kept. :func:`recipe` gives the staged settings that made the shipped multipliers and
:func:`train_stages` runs them (``docs/multiplier.md``).
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax import Array

from mbn.errors import MbnInputError
from mbn.networks.ctrnn import (
    CTRNN,
    Method,
    firing_rate,
    make_ctrnn,
    matvec,
    simulate,
    vector_field,
)
from mbn.networks.multiplier import (
    FIXED_POINT_TOL,
    REL_TOL,
    T_OVER_TAU,
    Multiplier,
    dense_grid,
    evaluate,
    multiply,
    training_pairs,
    validation_pairs,
)
from mbn.precision import cast, scope

__all__ = [
    "Params",
    "TrainConfig",
    "edge_points",
    "euler_from_rest",
    "init_params",
    "make_loss",
    "recipe",
    "rest_trajectory",
    "select_restart",
    "smooth_max",
    "train",
    "train_stages",
]


@dataclasses.dataclass(frozen=True, kw_only=True)
class TrainConfig:
    """Settings of :func:`train`. Defaults reproduce the paper's setup (section 2.1).

    Attributes:
        num_neurons: neurons of the multiplier (paper: 3).
        num_restarts: random restarts trained in parallel (vmap); the best by validation is kept.
        num_iterations: Adam iterations.
        learning_rate: peak Adam learning rate (cosine decay to 1 % of it).
        init_range: initial weights uniform in ``[-init_range, init_range]`` (paper: 10).
        grid_per_axis: training pairs per axis (paper: 10, i.e. 100 pairs).
        num_validation: random validation pairs (paper: 100).
        dt_over_tau: integration step in units of tau_m.
        method: integrator used in training.
        abs_weight: weight of the squared absolute error next to the log-ratio loss.
        edge_weight: weight of the squared absolute error on anchor points of the boundary of
            [0, 1]^2 (``num_edge_points`` per side; products 0 on the lower and left sides). The
            paper's pairs stay inside [0.05, 0.95]^2; without anchors the output is an
            extrapolation near the edges and corners (about 0.16 off at (1, 1)).
        dtype: floating type of training (float32 is about twice as fast on CPU); the training
            and its evaluation run in it whatever the process-wide setting
            (:mod:`mbn.precision`).
        fixed_point_weight: weight of the penalty on ``|dy/dt|`` at T (keeps the output a
            fixed point rather than a transient).
        clip_norm: global gradient-norm clip per restart.
        objective: ``"mean"`` (the losses above, averaged over the pairs) or ``"minimax"`` (for
            fine-tuning: on a grid of ``minimax_points`` per axis over [0, 1]^2, edges included,
            the smooth maximum ``t log mean exp(|e| / t)`` of the absolute error (``t`` =
            ``minimax_temperature``), plus ``minimax_rel_weight`` times the smooth maximum of the
            relative error over grid points whose product is at least ``minimax_rel_floor``
            (``t`` = 0.01), plus the fixed-point penalty; the training pairs, ``abs_weight`` and
            ``edge_weight`` are not used), or ``"count"`` (for fine-tuning towards the paper's
            criterion: on the same grid, the soft count ``mean sigmoid((rel - count_threshold) /
            count_width)`` of the grid points with product at least ``count_floor`` whose
            relative error ``rel`` exceeds the threshold, plus the fixed-point penalty; a point far
            outside costs no more than one just outside, so the fit gives up hopeless points near
            0 for the many it can keep within 5 %).
    """

    num_neurons: int = 3
    num_restarts: int = 128
    num_iterations: int = 1500
    learning_rate: float = 0.05
    init_range: float = 10.0
    grid_per_axis: int = 10
    num_validation: int = 100
    dt_over_tau: float = 0.1
    method: Method = "rk4"
    abs_weight: float = 1.0
    edge_weight: float = 1.0
    num_edge_points: int = 11
    fixed_point_weight: float = 1.0
    clip_norm: float = 10.0
    dtype: str = "float32"
    rel_loss: str = "log2"
    init_noise: float = 0.1
    grid_error_cap: float = 0.05
    objective: str = "mean"
    minimax_points: int = 41
    minimax_temperature: float = 0.001
    minimax_rel_weight: float = 0.2
    minimax_rel_floor: float = 0.04
    count_threshold: float = 0.04
    count_width: float = 0.005
    count_floor: float = 0.01

    def __post_init__(self) -> None:
        checks = {
            "num_neurons": self.num_neurons >= 1,
            "num_restarts": self.num_restarts >= 1,
            "num_iterations": self.num_iterations >= 0,
            "learning_rate": self.learning_rate > 0,
            "init_range": self.init_range > 0,
            "grid_per_axis": self.grid_per_axis >= 2,
            "num_validation": self.num_validation >= 1,
            "dt_over_tau": 0 < self.dt_over_tau <= 1,
            "abs_weight": self.abs_weight >= 0,
            "edge_weight": self.edge_weight >= 0,
            "num_edge_points": self.num_edge_points >= 2,
            "fixed_point_weight": self.fixed_point_weight >= 0,
            "clip_norm": self.clip_norm > 0,
            "minimax_points": self.minimax_points >= 2,
            "minimax_temperature": self.minimax_temperature > 0,
            "minimax_rel_weight": self.minimax_rel_weight >= 0,
            "minimax_rel_floor": 0 < self.minimax_rel_floor < 1,
            "count_threshold": self.count_threshold > 0,
            "count_width": self.count_width > 0,
            "count_floor": 0 < self.count_floor < 1,
        }
        for name, ok in checks.items():
            if not ok:
                raise MbnInputError(f"{name}: invalid value {getattr(self, name)!r}")
        if self.dtype not in ("float32", "float64"):
            raise MbnInputError(f"dtype: expected 'float32' or 'float64', got {self.dtype!r}")
        if self.method not in ("euler", "rk4"):
            raise MbnInputError(f"method: expected 'euler' or 'rk4', got {self.method!r}")
        if self.objective not in ("mean", "minimax", "count"):
            raise MbnInputError(
                f"objective: expected 'mean', 'minimax' or 'count', got {self.objective!r}"
            )


Params = dict[str, Array]


def net_from_params(p: Params) -> CTRNN:
    n = p["W"].shape[-1]
    return CTRNN(
        W=p["W"],
        WE=p["WE"],
        tau=jnp.ones(n, p["W"].dtype),
        bias=p["bias"],
        gain=jnp.ones(n, p["W"].dtype),
    )


def init_params(key: Array, cfg: TrainConfig, dtype: Any) -> Params:
    kw, ke, kb = jax.random.split(key, 3)
    n, a = cfg.num_neurons, cfg.init_range
    return {
        "W": jax.random.uniform(kw, (n, n), dtype, -a, a),
        "WE": jax.random.uniform(ke, (n, 2), dtype, -a, a),
        "bias": jax.random.uniform(kb, (n,), dtype, -a, a),
    }


def edge_points(num_per_side: int, dtype: Any = None) -> Array:
    """Points on the boundary of [0, 1]^2, ``num_per_side`` per side, shape ``(4 * (n - 1), 2)``."""
    t = np.linspace(0.0, 1.0, num_per_side)[:-1]
    sides = [
        np.stack(a, -1) for a in ((t, 0 * t), (1 + 0 * t, t), (1 - t, 1 + 0 * t), (0 * t, 1 - t))
    ]
    return jnp.asarray(np.concatenate(sides), dtype=dtype)


def rest_trajectory(
    W: Array, WE: Array, bias: Array, pairs: Array, h: float, num_steps: int
) -> tuple[Array, Array]:
    """Euler from rest with constant inputs; restarts batched on the leading axis of the weights.

    ``W (R, n, n)``, ``WE (R, n, 2)``, ``bias (R, n)``, ``pairs (P, 2)``; returns ``y_T (R, P, n)``
    and the states before each step ``(num_steps, R, P, n)``. Time is in units of tau_m. It is
    :func:`mbn.networks.ctrnn.integrate` (Euler, tau = 1, gain = 1) specialised for inputs that
    never change: their drive is computed once, and the states are recorded before each step as the
    adjoint needs them; through ``integrate`` a training run is 35 % slower.
    """
    drive = matvec(WE[:, None], pairs)  # (R, P, n), constant in time
    b = bias[:, None]
    w = W[:, None]

    def body(y: Array, _: None) -> tuple[Array, Array]:
        r = jax.nn.sigmoid(y + b)
        return y + h * (matvec(w, r) + drive - y), y

    y0 = jnp.zeros(drive.shape, drive.dtype)
    return jax.lax.scan(body, y0, None, length=num_steps)


@functools.partial(jax.custom_vjp, nondiff_argnums=(4, 5))
def euler_from_rest(
    W: Array, WE: Array, bias: Array, pairs: Array, h: float, num_steps: int
) -> Array:
    """Final state of :func:`rest_trajectory`, with a hand-written adjoint (BPTT).

    The adjoint runs the reverse recursion ``a_t = (1 - h) a_{t+1} + h sigma'(y_t) (W^T a_{t+1})``
    and accumulates the weight gradients elementwise, reducing over pairs once at the end; this is
    about 2.5x faster on CPU than differentiating the ``lax.scan`` automatically, which reduces
    over pairs at every step. ``tests/networks/test_multiplier.py`` checks it against ``jax.grad``.
    """
    return rest_trajectory(W, WE, bias, pairs, h, num_steps)[0]


def _euler_from_rest_fwd(
    W: Array, WE: Array, bias: Array, pairs: Array, h: float, num_steps: int
) -> tuple[Array, tuple[Array, ...]]:
    y_final, ys = rest_trajectory(W, WE, bias, pairs, h, num_steps)
    return y_final, (W, bias, pairs, ys)


def _euler_from_rest_bwd(
    h: float, num_steps: int, residuals: tuple[Array, ...], g: Array
) -> tuple[Array, Array, Array, Array]:
    W, bias, pairs, ys = residuals
    w_t = jnp.swapaxes(W, -1, -2)[:, None]
    b = bias[:, None]

    def body(carry: tuple[Array, Array, Array, Array], y: Array) -> tuple[tuple, None]:
        a, d_w, d_s, d_c = carry
        r = jax.nn.sigmoid(y + b)
        s = r * (1.0 - r) * matvec(w_t, a)
        d_w = d_w + a[..., :, None] * r[..., None, :]
        return ((1.0 - h) * a + h * s, d_w, d_s + s, d_c + a), None

    zeros = jnp.zeros_like(g)
    init = (g, jnp.zeros(g.shape + g.shape[-1:], g.dtype), zeros, zeros)
    (_, d_w, d_s, d_c), _ = jax.lax.scan(body, init, ys, reverse=True)
    d_we = h * jnp.einsum("rpi,pk->rik", d_c, pairs)
    return h * d_w.sum(1), d_we, h * d_s.sum(1), jnp.zeros_like(pairs)


euler_from_rest.defvjp(_euler_from_rest_fwd, _euler_from_rest_bwd)


def make_loss(cfg: TrainConfig, pairs: Array) -> Callable[[Params], Array]:
    """Training loss of every restart: params with a leading restart axis -> losses ``(R,)``."""
    num_pairs = pairs.shape[0]
    if cfg.objective in ("minimax", "count"):
        everything = dense_grid(cfg.minimax_points, pairs.dtype)
    else:
        everything = jnp.concatenate([pairs, edge_points(cfg.num_edge_points, pairs.dtype)])
    target = everything[:, 0] * everything[:, 1]

    def inverse_from(floor: float) -> Array:
        """``1 / target`` where the target is at least ``floor``, else 0 (relative errors)."""
        kept = target >= floor
        return jnp.where(kept, 1.0 / jnp.where(kept, target, 1.0), 0.0)

    relative_scale = inverse_from(cfg.minimax_rel_floor)
    counted = target >= cfg.count_floor
    count_scale = inverse_from(cfg.count_floor)
    num_steps = round(T_OVER_TAU / cfg.dt_over_tau)
    inputs = jnp.broadcast_to(everything, (num_steps, *everything.shape))

    def final_state(p: Params) -> Array:
        if cfg.method == "euler":
            return euler_from_rest(
                p["W"], p["WE"], p["bias"], everything, cfg.dt_over_tau, num_steps
            )

        def one(q: Params) -> Array:
            y0 = jnp.zeros((everything.shape[0], cfg.num_neurons), pairs.dtype)
            net = net_from_params(q)
            return simulate(net, y0, inputs, cfg.dt_over_tau, method=cfg.method, record=False)[0]

        return jax.vmap(one)(p)

    def loss(p: Params) -> Array:
        y = final_state(p)  # (R, E, n)
        net = net_from_params({k: v[:, None] for k, v in p.items()})
        out = firing_rate(net, y)[..., -1]
        speed = vector_field(net, y, everything)  # dy/dt at T, in units of 1/tau_m
        fixed_point = cfg.fixed_point_weight * jnp.mean(speed**2, (-2, -1))
        if cfg.objective == "minimax":
            err = jnp.abs(out - target)
            return (
                smooth_max(err, cfg.minimax_temperature)
                + cfg.minimax_rel_weight * smooth_max(err * relative_scale, 0.01)
                + fixed_point
            )
        if cfg.objective == "count":
            outside = jax.nn.sigmoid(
                (jnp.abs(out - target) * count_scale - cfg.count_threshold) / cfg.count_width
            )
            return jnp.sum(jnp.where(counted, outside, 0.0), -1) / jnp.sum(counted) + fixed_point
        sq_err = (out - target) ** 2
        log_ratio = jnp.log(out[:, :num_pairs]) - jnp.log(target[:num_pairs])
        if cfg.rel_loss == "cauchy":  # robust: saturates for pairs far outside 5 %
            rel_term = jnp.mean(jnp.log1p((log_ratio / REL_TOL) ** 2), -1) * REL_TOL**2
        else:
            rel_term = jnp.mean(log_ratio**2, -1)
        return (
            rel_term
            + cfg.abs_weight * jnp.mean(sq_err[:, :num_pairs], -1)
            + cfg.edge_weight * jnp.mean(sq_err[:, num_pairs:], -1)
            + fixed_point
        )

    return loss


def smooth_max(values: Array, temperature: float) -> Array:
    """``t log mean exp(v / t)`` over the last axis: between ``max v - t log n`` and ``max v``."""
    n = values.shape[-1]
    return temperature * (jax.nn.logsumexp(values / temperature, -1) - jnp.log(n))


def train(
    key: Array,
    config: TrainConfig | None = None,
    *,
    init: Multiplier | None = None,
    progress: Callable[[int, int], None] | None = None,
    validation_key: Array | None = None,
) -> tuple[Multiplier, dict[str, Any]]:
    """Train a multiplier by BPTT from ``config.num_restarts`` random starts.

    With ``init`` (warm start, used to fine-tune), every restart starts from ``init``'s weights
    plus Gaussian noise of standard deviation ``config.init_noise`` (restart 0 without noise).

    Args:
        key: JAX PRNG key (the only source of randomness).
        config: settings; defaults are the paper's setup.
        progress: optional callback ``progress(done, total)`` called between chunks of iterations.

    Returns:
        ``(multiplier, metrics)``: the restart that passes the fixed-point check with the highest
        fraction of validation pairs within 5 % (ties broken by the smaller dense-grid error), and
        its metrics (:func:`evaluate`) plus training information.
    """
    cfg = config or TrainConfig()
    with scope(cfg.dtype):
        return _train(key, cfg, init, progress, validation_key)


def _train(
    key: Array,
    cfg: TrainConfig,
    init: Multiplier | None,
    progress: Callable[[int, int], None] | None,
    validation_key: Array | None,
) -> tuple[Multiplier, dict[str, Any]]:
    dtype = jnp.dtype(cfg.dtype)
    if init is not None:
        init = dataclasses.replace(init, net=cast(init.net, cfg.dtype))
    k_init, k_val = jax.random.split(key)
    if validation_key is not None:
        k_val = validation_key
    pairs = training_pairs(cfg.grid_per_axis, dtype)
    validation = validation_pairs(k_val, cfg.num_validation, dtype)
    loss = make_loss(cfg, pairs)
    schedule = optax.cosine_decay_schedule(
        cfg.learning_rate, max(cfg.num_iterations, 1), alpha=0.01
    )
    opt = optax.chain(optax.clip_by_global_norm(cfg.clip_norm), optax.adam(schedule))

    if init is None:
        params = jax.vmap(lambda k: init_params(k, cfg, dtype))(
            jax.random.split(k_init, cfg.num_restarts)
        )
    else:
        if init.num_neurons != cfg.num_neurons:
            raise MbnInputError(
                f"init: has {init.num_neurons} neurons, the config asks for {cfg.num_neurons}"
            )
        base = {k: jnp.asarray(getattr(init.net, k), dtype) for k in ("W", "WE", "bias")}
        noise_keys = jax.random.split(k_init, 3)
        params = {
            k: base[k][None]
            + cfg.init_noise
            * jnp.arange(cfg.num_restarts).clip(max=1).reshape((-1,) + (1,) * base[k].ndim)
            * jax.random.normal(nk, (cfg.num_restarts, *base[k].shape), dtype)
            for k, nk in zip(("W", "WE", "bias"), noise_keys, strict=True)
        }
    opt_state = jax.vmap(opt.init)(params)

    def total(p: Params) -> tuple[Array, Array]:
        values = loss(p)
        return jnp.sum(values), values  # restarts are independent: d total / d p_r = d loss_r

    def apply(g: Params, s: optax.OptState, p: Params) -> tuple[Params, optax.OptState]:
        g = jax.tree.map(lambda a: jnp.where(jnp.isfinite(a), a, 0.0), g)
        updates, s = opt.update(g, s, p)
        return optax.apply_updates(p, updates), s

    def all_updates(p: Params, s: optax.OptState) -> tuple[Params, optax.OptState, Array]:
        (_, values), grad = jax.value_and_grad(total, has_aux=True)(p)
        p, s = jax.vmap(apply)(grad, s, p)  # per-restart clipping and Adam moments
        return p, s, values

    chunk = 50

    @jax.jit
    def run_chunk(p: Params, s: optax.OptState) -> tuple[Params, optax.OptState, Array]:
        def body(carry: tuple, _: None) -> tuple:
            p, s = carry
            p, s, value = all_updates(p, s)
            return (p, s), value

        (p, s), values = jax.lax.scan(body, (p, s), None, length=chunk)  # type: ignore[var-annotated]
        return p, s, values[-1]

    start = time.perf_counter()
    done = 0
    losses = jnp.full((cfg.num_restarts,), jnp.inf)
    while done < cfg.num_iterations:
        params, opt_state, losses = run_chunk(params, opt_state)
        losses.block_until_ready()  # honest timing and progress (dispatch is asynchronous)
        done += chunk
        if progress is not None:
            progress(min(done, cfg.num_iterations), cfg.num_iterations)
    train_seconds = time.perf_counter() - start

    best, summary = select_restart(params, validation, cfg)
    metrics = evaluate(best, validation.astype(best.net.dtype), precision=cfg.dtype)
    metrics["training"] = {
        **dataclasses.asdict(cfg),
        "iterations_run": done,
        "train_seconds": round(train_seconds, 2),
        "restart_selected": summary["index"],
        "restarts_passing_fixed_point": summary["num_fixed_point_ok"],
        "final_loss_selected": float(losses[summary["index"]]),
        "dtype": str(np.dtype(dtype)),
    }
    return best, metrics


def recipe(num_neurons: int = 3) -> tuple[TrainConfig, ...]:
    """The training stages used for the shipped multipliers (see ``docs/multiplier.md``).

    Stage 1 trains random restarts; each later stage fine-tunes the best of the previous one
    (warm start with small noise) with other loss weights.
    """
    common: dict[str, Any] = {"num_neurons": num_neurons, "method": "euler", "learning_rate": 0.1}
    if num_neurons <= 3:
        # One stage, selected by the paper's criterion (pairs within 5 %) alone: with 3 neurons,
        # pushing the corner (1, 1) within 0.05 costs a third of the pairs within 5 %.
        return (
            TrainConfig(
                **common, num_restarts=128, num_iterations=1500, edge_weight=1.0, grid_error_cap=1.0
            ),
        )
    return (
        TrainConfig(
            **common,
            num_restarts=64,
            num_iterations=2000,
            edge_weight=3.0,
            abs_weight=3.0,
            grid_error_cap=0.01,
        ),
        TrainConfig(
            **{**common, "learning_rate": 0.01},
            num_restarts=16,
            num_iterations=1500,
            edge_weight=10.0,
            abs_weight=10.0,
            grid_error_cap=0.01,
        ),
        # The largest errors are then on the edges and at (1, 1): minimise the largest one.
        TrainConfig(
            **{**common, "learning_rate": 0.003},
            objective="minimax",
            num_restarts=2,
            num_iterations=1500,
            init_noise=0.01,
            grid_error_cap=0.01,
        ),
    )


def train_stages(
    key: Array,
    stages: tuple[TrainConfig, ...],
    *,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[Multiplier, dict[str, Any]]:
    """Run :func:`train` stage after stage, each warm-started from the previous best.

    All stages draw the same validation pairs (from ``key``); the metrics are those of the last
    stage, with every stage's training block under ``"stages"``.
    """
    if not stages:
        raise MbnInputError("stages: give at least one training stage")
    total = sum(st.num_iterations for st in stages)
    offset = 0
    mul: Multiplier | None = None
    blocks = []
    metrics: dict[str, Any] = {}
    for number, stage in enumerate(stages):

        def report(done: int, _total: int, base: int = offset) -> None:
            if progress is not None:
                progress(min(base + done, total), total)

        stage_key = key if number == 0 else jax.random.fold_in(key, number)
        # the validation key must not change between stages: train() splits it off `key`
        _, k_val = jax.random.split(key)
        mul, metrics = train(stage_key, stage, init=mul, progress=report, validation_key=k_val)
        blocks.append(metrics.pop("training"))
        offset += stage.num_iterations
    assert mul is not None
    metrics["training"] = {
        "stages": blocks,
        "train_seconds": round(sum(b["train_seconds"] for b in blocks), 2),
    }
    return mul, metrics


def select_restart(params: Params, validation: Array, cfg: TrainConfig) -> tuple[Multiplier, dict]:
    """Pick the best restart by validation among those that pass the fixed-point check."""
    nets = jax.vmap(net_from_params)(params)
    batched = Multiplier(
        net=nets, output=cfg.num_neurons - 1, dt_over_tau=cfg.dt_over_tau, method=cfg.method
    )
    target = validation[:, 0] * validation[:, 1]
    # every validation pair against every restart: (num_val, R, 2)
    val = jnp.broadcast_to(validation[:, None, :], (validation.shape[0], cfg.num_restarts, 2))
    prec = cfg.dtype
    out_t = np.asarray(multiply(batched, val, precision=prec))
    out_2t = np.asarray(multiply(batched, val, t_over_tau=2 * T_OVER_TAU, precision=prec))
    out_fine = np.asarray(multiply(batched, val, dt_over_tau=cfg.dt_over_tau / 10, precision=prec))
    tgt = np.asarray(target)[:, None]
    within = np.mean(np.abs(out_t - tgt) / tgt <= REL_TOL, axis=0)
    drift = np.maximum(np.abs(out_2t - out_t).max(axis=0), np.abs(out_fine - out_t).max(axis=0))
    ok = np.isfinite(out_t).all(axis=0) & (drift <= FIXED_POINT_TOL)
    grid = dense_grid(101, dtype=validation.dtype)[:, None, :]
    grid_out = np.asarray(
        multiply(
            batched,
            jnp.broadcast_to(grid, (grid.shape[0], cfg.num_restarts, 2)),
            precision=prec,
        )
    )
    grid_err = np.abs(grid_out - np.asarray(grid[:, 0, 0] * grid[:, 0, 1])[:, None]).max(axis=0)
    grid_err = np.where(np.isfinite(grid_err), grid_err, np.inf)
    # Fixed point first, then restarts within the grid-error cap, then most pairs within 5 %.
    order = np.lexsort((grid_err, -within, grid_err > cfg.grid_error_cap, ~ok))
    index = int(order[0])
    chosen = jax.tree.map(lambda a: a[index], params)
    mul = Multiplier(
        net=make_ctrnn(chosen["W"], chosen["WE"], 1.0, bias=chosen["bias"], name="multiplier"),
        output=cfg.num_neurons - 1,
        dt_over_tau=cfg.dt_over_tau,
        method=cfg.method,
    )
    return mul, {"index": index, "num_fixed_point_ok": int(ok.sum())}
