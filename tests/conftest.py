"""Test configuration: float64 by default (tests that need float32 ask for it explicitly)."""

import jax

jax.config.update("jax_enable_x64", True)
