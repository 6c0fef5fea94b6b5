"""Equilibria of a CTRNN held at constant inputs: the mechanism behind a behaviour.

With the inputs ``I`` held constant, eq. 1 (``docs/ctrnn.md``) rests where

    0 = -y + W r(y) + WE I,        r(y) = sigma(gain (y + bias)),

and every such ``y`` lies on the image of the firing rates, ``y = W r + WE I`` with ``r`` in
``(0, 1)^n``. :func:`fixed_points` starts Powell's hybrid method (``scipy.optimize.root``, with
the exact Jacobian) from that image at a grid of firing rates (each neuron near off, half on and
near on) and at seeded random ones, keeps the roots whose residual is below ``tol`` (relative to
the size of the potentials), merges the duplicates and classifies each by the eigenvalues of the
linearised flow ``diag(1/tau) (-1 + W diag(gain r (1 - r)))``: stable when every real part is
negative. A multistart search finds every equilibrium of a 3-neuron network in practice but
proves nothing: :attr:`FixedPoint.residual` says how well each one solves the equation, and a
test checks the count against simulation for networks whose equilibria are known.

NumPy and SciPy, at the edge (an analysis, not a rollout).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import root

from mbn.errors import MbnInputError
from mbn.networks.ctrnn import CTRNN

__all__ = ["FixedPoint", "fixed_points"]

#: Firing rates of the grid of starts, per neuron.
GRID_RATES = (0.02, 0.5, 0.98)


@dataclass(frozen=True)
class FixedPoint:
    """One equilibrium.

    Attributes:
        y: the potentials ``(n,)``.
        rates: the firing rates ``sigma(gain (y + bias))`` ``(n,)``.
        eigenvalues: of the linearised flow there (``(n,)``, complex), in 1/s.
        stable: every eigenvalue's real part below 0.
        residual: ``max |dy/dt| tau`` there (how well it solves the equation).
    """

    y: np.ndarray
    rates: np.ndarray
    eigenvalues: np.ndarray
    stable: bool
    residual: float


def _params(net: CTRNN) -> tuple[np.ndarray, ...]:
    parts = tuple(np.asarray(getattr(net, f), dtype=np.float64) for f in ("W", "WE", "tau"))
    bias = np.asarray(net.bias, dtype=np.float64)
    gain = np.asarray(net.gain, dtype=np.float64)
    if parts[0].ndim != 2:
        raise MbnInputError(
            f"fixed_points takes one network (W of shape (n, n)), got {parts[0].shape}"
        )
    return (*parts, bias, gain)


def _rates(y: np.ndarray, bias: np.ndarray, gain: np.ndarray) -> np.ndarray:
    z = gain * (y + bias)
    return 0.5 * (1.0 + np.tanh(0.5 * z))  # the logistic, without overflow


def fixed_points(
    net: CTRNN,
    inputs: ArrayLike,
    *,
    random_starts: int = 64,
    seed: int = 0,
    tol: float = 1e-8,
) -> list[FixedPoint]:
    """Every equilibrium the multistart search finds of ``net`` at the constant ``inputs``
    ``(m,)``, the stable ones first, then by their firing rates.

    ``random_starts``: starts at uniform random firing rates beside the ``3^n`` grid (a seeded
    NumPy generator, ``seed``); ``tol``: the largest residual kept, relative to ``1 + max|y|``.
    """
    W, WE, tau, bias, gain = _params(net)
    n = W.shape[0]
    u = np.asarray(inputs, dtype=np.float64)
    if u.shape != (WE.shape[1],):
        raise MbnInputError(f"fixed_points: inputs of shape ({WE.shape[1]},), got {u.shape}")
    if not np.all(np.isfinite(u)):
        raise MbnInputError("fixed_points: inputs must be finite")
    drive = WE @ u

    def field(y: np.ndarray) -> np.ndarray:
        return -y + W @ _rates(y, bias, gain) + drive

    def jacobian(y: np.ndarray) -> np.ndarray:
        r = _rates(y, bias, gain)
        return -np.eye(n) + W * (gain * r * (1.0 - r))[None, :]

    rng = np.random.default_rng(seed)
    grid = np.array(list(itertools.product(GRID_RATES, repeat=n)), dtype=np.float64)
    starts = np.concatenate([grid, rng.uniform(0.0, 1.0, (random_starts, n))])
    found: list[FixedPoint] = []
    for r0 in starts:
        sol = root(field, W @ r0 + drive, jac=jacobian, method="hybr")
        y = np.asarray(sol.x, dtype=np.float64)
        residual = float(np.max(np.abs(field(y))))
        if not np.all(np.isfinite(y)) or residual > tol * (1.0 + float(np.max(np.abs(y)))):
            continue
        r = _rates(y, bias, gain)
        if any(
            np.allclose(r, p.rates, rtol=0.0, atol=1e-7)
            and np.allclose(y, p.y, rtol=1e-6, atol=1e-6)
            for p in found
        ):
            continue
        eig = np.linalg.eigvals(jacobian(y) / tau[:, None])
        found.append(FixedPoint(y, r, eig, bool(np.all(eig.real < 0.0)), residual))
    return sorted(found, key=lambda p: (not p.stable, *p.rates.tolist()))
