"""How well an interpreter emulates the networks it is programmed with (``mbn pnn check``).

Random piecewise-constant input sequences drive both the original network and the interpreter
running that network's program; the figure of merit is, per sequence, the largest absolute
difference over time between the firing rates of chosen output neurons.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from mbn.errors import MbnInputError
from mbn.networks.ctrnn import CTRNN, Method, check_dt, simulate
from mbn.networks.multiplier import Multiplier
from mbn.networks.programmable import (
    DEFAULT_TAU_RATIO,
    build_interpreter,
    differing_connections,
    run,
    run_network,
)
from mbn.paper import DEFAULT_TAU, published_lf, published_rf
from mbn.precision import NETWORKS, Precision, cast, scope

__all__ = ["EmulationConfig", "emulation_check", "piecewise_constant_inputs", "published_check"]


def piecewise_constant_inputs(
    key: Array,
    num_sequences: int,
    num_steps: int,
    hold_steps: int,
    num_inputs: int,
    dtype: Any = None,
) -> Array:
    """Inputs uniform in [0, 1], redrawn every ``hold_steps`` steps.

    Returns shape ``(num_steps, num_sequences, num_inputs)`` (time first, as the integrators take).
    """
    if hold_steps < 1 or num_steps < 1:
        raise MbnInputError("hold_steps and num_steps must be >= 1")
    num_segments = -(-num_steps // hold_steps)
    values = jax.random.uniform(
        key, (num_segments, num_sequences, num_inputs), dtype=dtype or jnp.zeros(()).dtype
    )
    return jnp.repeat(values, hold_steps, axis=0)[:num_steps]


@dataclasses.dataclass(frozen=True, kw_only=True)
class EmulationConfig:
    """Settings of the emulation check (documented defaults, ``docs/programmable.md``).

    Attributes:
        num_sequences: random input sequences per program (paper-free choice: 200).
        seconds: length of each sequence in seconds.
        hold: seconds each input value is held.
        dt: integration step in seconds (RK4); 0.005 s is h/tau_m = 0.1 for tau = 0.5 s.
        method: integrator.
        outputs: neurons whose firing rates are compared (0-based; the paper's neurons 2 and 3).
        tau_ratio: multiplier time constant / network time constant.
        margin: bound margin of :func:`~mbn.networks.programmable.differing_connections`.
        start: ``"settled"`` (default): every run starts from the state the original network
            reaches after ``settle`` seconds with the sequence's first input (the interpreter's
            original neurons start there too, its multipliers settled); ``"rest"``: from ``y = 0``,
            where the published networks (weights of hundreds) make a fast transient that no
            multiplier at tau/10 can follow (``docs/programmable.md``).
        settle: seconds of the settling run of ``start="settled"``.
    """

    num_sequences: int = 200
    seconds: float = 20.0
    hold: float = 1.0
    dt: float = 0.005
    method: Method = "rk4"
    outputs: tuple[int, ...] = (1, 2)
    tau_ratio: float = DEFAULT_TAU_RATIO
    margin: float = 0.1
    start: str = "settled"
    settle: float = 5.0

    def __post_init__(self) -> None:
        if self.start not in ("settled", "rest"):
            raise MbnInputError(f"start: expected 'settled' or 'rest', got {self.start!r}")
        checks = {
            "num_sequences": self.num_sequences >= 1,
            "seconds": self.seconds > 0,
            "hold": self.hold > 0,
            "dt": self.dt > 0,
            "tau_ratio": self.tau_ratio > 0,
            "margin": self.margin >= 0,
            "settle": self.settle >= 0,
        }
        for name, ok in checks.items():
            if not ok:
                raise MbnInputError(f"{name}: invalid value {getattr(self, name)!r}")

    @property
    def num_steps(self) -> int:
        """Integration steps per sequence."""
        return round(self.seconds / self.dt)

    @property
    def hold_steps(self) -> int:
        """Steps each input value is held."""
        return max(1, round(self.hold / self.dt))


def emulation_check(
    key: Array,
    networks: Sequence[CTRNN],
    multiplier: Multiplier,
    config: EmulationConfig | None = None,
    *,
    precision: Precision = NETWORKS,
) -> dict[str, Any]:
    """Build one interpreter from the connections in which ``networks`` differ and compare, in
    ``precision`` (:mod:`mbn.precision`).

    The interpreter is built from ``networks[0]``; each network is emulated with its own
    program, in exact mode and with ``multiplier``, on the same random input sequences.

    Returns:
        ``{"exact": {"max_abs_output_diff"}, "trained": {"median_max_abs_output_diff",
        "p95_max_abs_output_diff", "max_max_abs_output_diff"}, "num_sequences", ...}`` where
        ``num_sequences`` counts sequences over all programs.
    """
    cfg = config or EmulationConfig()
    if len(networks) < 2:
        raise MbnInputError("networks: give at least two networks to tell apart")
    with scope(precision):
        nets = [cast(n, precision) for n in networks]
        mul = dataclasses.replace(multiplier, net=cast(multiplier.net, precision))
        return _emulation_check(key, nets, mul, cfg)


def _emulation_check(
    key: Array, networks: Sequence[CTRNN], multiplier: Multiplier, cfg: EmulationConfig
) -> dict[str, Any]:
    base = networks[0]
    programmable = differing_connections(base, networks[1], margin=cfg.margin)
    for other in networks[2:]:
        seen = {p.connection for p in programmable}
        programmable += [
            p
            for p in differing_connections(base, other, margin=cfg.margin)
            if p.connection not in seen
        ]
    interp = build_interpreter(base, programmable, multiplier, tau_ratio=cfg.tau_ratio)
    stability = check_dt(interp.net, cfg.dt, cfg.method, name="dt")
    data = piecewise_constant_inputs(
        key, cfg.num_sequences, cfg.num_steps, cfg.hold_steps, base.num_inputs, base.dtype
    )
    rest = jnp.zeros((cfg.num_sequences, base.num_neurons), base.dtype)
    settle_steps = round(cfg.settle / cfg.dt)
    outs = list(cfg.outputs)
    exact: list[np.ndarray] = []
    trained: list[np.ndarray] = []
    for net in networks:
        program = interp.program_of(net)
        y0 = rest
        if cfg.start == "settled" and settle_steps > 0:
            first = jnp.broadcast_to(data[:1], (settle_steps, *data.shape[1:]))
            y0 = simulate(net, rest, first, cfg.dt, method=cfg.method, record=False)[0]
        reference = run_network(net, y0, data, cfg.dt, method=cfg.method)[..., outs]
        for exact_mode, sink in ((True, exact), (False, trained)):
            emulated = run(interp, y0, data, program, cfg.dt, method=cfg.method, exact=exact_mode)[
                ..., outs
            ]
            sink.append(np.asarray(jnp.max(jnp.abs(emulated - reference), axis=(0, 2))))
    exact_all, trained_all = np.concatenate(exact), np.concatenate(trained)
    return {
        "exact": {"max_abs_output_diff": float(exact_all.max())},
        "trained": {
            "median_max_abs_output_diff": float(np.median(trained_all)),
            "p95_max_abs_output_diff": float(np.percentile(trained_all, 95)),
            "max_max_abs_output_diff": float(trained_all.max()),
        },
        "per_program": [
            {
                "exact_max_abs_output_diff": float(e.max()),
                "median_max_abs_output_diff": float(np.median(t)),
                "p95_max_abs_output_diff": float(np.percentile(t, 95)),
            }
            for e, t in zip(exact, trained, strict=True)
        ],
        "num_sequences": int(trained_all.size),
        "connections": [
            {
                "connection": str(p.connection),
                "paper_name": p.connection.paper_name,
                "min": p.lower,
                "max": p.upper,
            }
            for p in programmable
        ],
        "programs": [np.asarray(interp.program_of(n)).tolist() for n in networks],
        "interpreter_neurons": interp.num_neurons,
        "dt_over_stability_limit": stability,
        "config": dataclasses.asdict(cfg),
    }


def published_check(
    key: Array,
    multiplier: Multiplier,
    config: EmulationConfig | None = None,
    tau: float = DEFAULT_TAU,
    *,
    precision: Precision = NETWORKS,
) -> dict[str, Any]:
    """:func:`emulation_check` on the paper's published RF and LF matrices (section 3.1)."""
    with scope(precision):
        nets = [published_rf(tau), published_lf(tau)]
    return emulation_check(key, nets, multiplier, config, precision=precision)
