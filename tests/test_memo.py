"""The memo that makes factories give one object for equal arguments (mbn.memo), and what it is
for: one compiled rollout per controller, config and shapes in a process."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.control.ctrnn import ctrnn_controller, interpreter_controller, with_tiles
from mbn.memo import frozen, memoized
from mbn.world.sensors import NoiseConfig


def test_equal_arguments_give_the_same_object_and_others_another():
    made = []

    @memoized
    def factory(a, *, b=None):
        made.append((a, b))
        return object()

    x = factory(1, b=np.array([1.0, 2.0]))
    assert factory(1, b=np.array([1.0, 2.0])) is x  # arrays compared by value
    assert factory(1, b=np.array([1.0, 3.0])) is not x
    assert factory(1, b=np.array([1.0, 2.0], np.float32)) is not x  # dtype matters
    assert factory(2, b=np.array([1.0, 2.0])) is not x
    assert len(made) == 4


def test_unhashable_arguments_are_made_anew():
    calls = []

    @memoized
    def factory(a):
        calls.append(a)
        return object()

    class Open:
        __hash__ = None  # type: ignore[assignment]

    o = Open()
    assert factory(o) is not factory(o)
    assert len(calls) == 2
    with pytest.raises(TypeError):
        frozen(o)


def test_a_traced_array_is_not_frozen():
    def f(x):
        with pytest.raises(TypeError):
            frozen(x)
        return x

    jax.jit(f)(jnp.ones(2))


def test_controller_factories_are_memoized():
    noise = NoiseConfig()
    assert ctrnn_controller(dt=0.1, substeps=20, noise=noise) is ctrnn_controller(
        dt=0.1, substeps=20, noise=NoiseConfig()
    )
    assert ctrnn_controller(dt=0.1, substeps=20) is not ctrnn_controller(dt=0.1, substeps=40)
    assert interpreter_controller(substeps=80) is interpreter_controller(substeps=80)
    assert with_tiles(2) is with_tiles(2)
