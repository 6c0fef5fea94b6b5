"""Arrays made on the host, put on the device without compiling anything.

``jnp.asarray`` of a NumPy array compiles a small program (``jit(stage)``) for every new shape
and dtype; ``jax.device_put`` copies the array as it is (in JAX's default precision: float64
becomes float32 unless ``jax_enable_x64`` is on, rounded as ``jnp.asarray`` rounds it). A run
meets hundreds of such shapes (mazes, start poses, initial states), so the code that makes
arrays on the host puts them on the device with :func:`put` (``docs/speed.md``).
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np
from jax import Array

__all__ = ["put"]


def put(value: Any, dtype: Any = None) -> Array:
    """``value`` as a device array (of ``dtype``, converted on the host, when given)."""
    return jax.device_put(np.asarray(value, dtype))
