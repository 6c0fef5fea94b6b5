"""Floating-point precision, explicit: every entry point that computes runs in the precision it is
given, whatever the process-wide JAX setting (``docs/precision.md``).

JAX computes in float32 unless ``jax_enable_x64`` is on. ``mbn`` never flips that switch for the
process: :func:`scope` turns it on or off for the duration of one call (``jax.enable_x64`` as a
context manager), so a library call gives the same numbers in a notebook, in a test and from the
command line.

* The robot experiments (rollouts, evolution, tests, ``mbn reproduce``, ``mbn evaluate``) run in
  **float32**: they were evolved and tested so, and it halves memory traffic.
* The network-side checks (multiplier training and evaluation, the emulation check, ``mbn mul``,
  ``mbn pnn``) and the geometry commands (``mbn sonar``, ``mbn drive``) run in **float64**.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any, TypeVar

import jax
import jax.numpy as jnp

__all__ = ["NETWORKS", "PRECISIONS", "ROBOT", "Precision", "cast", "dtype_of", "scope"]

T = TypeVar("T")

#: "float32" or "float64" (checked by :func:`scope` and :func:`dtype_of`).
Precision = str
PRECISIONS: tuple[str, ...] = ("float32", "float64")
#: The precision of the robot experiments.
ROBOT: Precision = "float32"
#: The precision of the network-side checks and the geometry commands.
NETWORKS: Precision = "float64"


@contextlib.contextmanager
def scope(precision: str) -> Iterator[None]:
    """Compute in ``precision`` ("float32" or "float64") inside the block."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be float32 or float64, got {precision!r}")
    with jax.enable_x64(precision == "float64"):
        yield


def dtype_of(precision: str) -> Any:
    """The JAX dtype of ``precision``."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be float32 or float64, got {precision!r}")
    return jnp.float64 if precision == "float64" else jnp.float32


def cast(tree: T, precision: str) -> T:
    """``tree`` (a pytree: a CTRNN, arrays, ...) with its floating arrays in ``precision``
    (call inside :func:`scope` of the same precision)."""
    dtype = dtype_of(precision)

    def one(a: Any) -> Any:
        if hasattr(a, "dtype") and jnp.issubdtype(a.dtype, jnp.floating):
            return jnp.asarray(a, dtype)
        return a

    return jax.tree.map(one, tree)
