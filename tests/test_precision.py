"""Precision is explicit: a computation runs in the precision it is given, whatever the
process-wide JAX setting, so a library call gives the same numbers in a notebook (x64 off), in
the tests (x64 on) and from the command line."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import pytest

from mbn.precision import cast, dtype_of, scope

_EVALUATE = """
import json, sys, jax
{setup}
from mbn.networks.multiplier import evaluate, load_default, validation_pairs
mul = load_default(6)
print(json.dumps(evaluate(mul, validation_pairs(jax.random.key(4), 20), grid_points=11,
                          precision=sys.argv[1])))
"""


def _evaluate_in_a_process(x64: bool, precision: str) -> dict:
    setup = "jax.config.update('jax_enable_x64', True)" if x64 else ""
    env = {k: v for k, v in os.environ.items() if k != "JAX_ENABLE_X64"}
    out = subprocess.run(
        [sys.executable, "-c", _EVALUATE.format(setup=setup), precision],
        capture_output=True,
        text=True,
        check=True,
        env=env,
    )
    return json.loads(out.stdout)


# float64 is the tests' own setting: the float32 case is the one a library user would meet
@pytest.mark.slow  # two processes each; with the test below
@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_a_library_call_gives_the_same_numbers_whatever_the_process_wide_setting(precision):
    assert _evaluate_in_a_process(False, precision) == _evaluate_in_a_process(True, precision)


@pytest.mark.slow
def test_float32_and_float64_differ_so_the_test_above_can_fail():
    a = _evaluate_in_a_process(False, "float32")
    b = _evaluate_in_a_process(False, "float64")
    assert a["max_abs_error_grid"] != b["max_abs_error_grid"]
    assert a["max_abs_error_grid"] == pytest.approx(b["max_abs_error_grid"], abs=1e-5)


def test_scope_sets_the_precision_for_the_block_only():
    before = jnp.zeros(()).dtype
    with scope("float32"):
        assert jnp.zeros(()).dtype == jnp.float32
        with scope("float64"):
            assert jnp.zeros(()).dtype == jnp.float64
            assert (
                cast({"a": jnp.ones(2, jnp.float32), "i": jnp.ones(2, jnp.int32)}, "float64")[
                    "a"
                ].dtype
                == jnp.float64
            )
        assert jnp.zeros(()).dtype == jnp.float32
    assert (
        jnp.zeros(()).dtype == before == (jnp.float64 if jax.config.jax_enable_x64 else jnp.float32)
    )
    with pytest.raises(ValueError, match="float32 or float64"):
        dtype_of("float16")
