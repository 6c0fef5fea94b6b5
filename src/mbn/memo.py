"""Factories that give the same object for the same arguments, so that JAX compiles once.

``jax.jit`` keeps a compiled program per function object and per value of its static
arguments. A controller made by a factory (:func:`mbn.control.ctrnn.ctrnn_controller`, ...) is a
closure: made again for every test, validation or stage, it is a new function, and every
rollout that takes it as a static argument would be traced and compiled again for the same
shapes. :func:`memoized` makes such a factory return the very same closure for equal
arguments (arrays compared by value), so that a process compiles each rollout shape once
(``docs/speed.md``). A call whose arguments cannot be compared by value (a traced array, an
unhashable object) is made anew, as without the memo: it is slower, never wrong.
"""

from __future__ import annotations

import functools
import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

__all__ = ["frozen", "memoized"]

F = TypeVar("F", bound=Callable[..., Any])

#: Factories keep at most this many results each (the oldest is dropped first).
MAX_ENTRIES = 256


class _UnhashableError(Exception):
    pass


def frozen(value: Any) -> Any:
    """A hashable stand-in for ``value`` that compares as ``value`` does by value: arrays by
    dtype, shape and bytes, lists and tuples and dicts by their items, ranges by their ends;
    anything else must be hashable itself. Raises TypeError for what cannot be compared so (a
    traced array)."""
    try:
        return _frozen(value)
    except _UnhashableError as exc:
        raise TypeError(str(exc)) from None


def _frozen(value: Any) -> Any:
    if isinstance(value, np.ndarray) or type(value).__module__.startswith("jax"):
        try:
            a = np.asarray(value)
        except Exception as exc:  # a tracer: no value to compare
            raise _UnhashableError(f"{type(value).__name__} has no value") from exc
        if a.dtype == object:
            raise _UnhashableError("an object array")
        return ("array", a.dtype.str, a.shape, a.tobytes())
    if isinstance(value, range):
        return ("range", value.start, value.stop, value.step)
    if isinstance(value, (list, tuple)):
        return (type(value).__name__, tuple(_frozen(v) for v in value))
    if isinstance(value, dict):
        return ("dict", tuple(sorted((k, _frozen(v)) for k, v in value.items())))
    try:
        hash(value)
    except TypeError as exc:
        raise _UnhashableError(str(exc)) from exc
    return value


def memoized(factory: F) -> F:
    """``factory`` returning, for arguments equal by value (:func:`frozen`), the object it
    returned the first time (up to :data:`MAX_ENTRIES` kept, thread-safe)."""
    cache: OrderedDict[Any, Any] = OrderedDict()
    lock = threading.Lock()

    @functools.wraps(factory)
    def made(*args: Any, **kwargs: Any) -> Any:
        try:
            key = (frozen(args), frozen(tuple(sorted(kwargs.items()))))
        except TypeError:
            return factory(*args, **kwargs)
        with lock:
            if key in cache:
                cache.move_to_end(key)
                return cache[key]
        result = factory(*args, **kwargs)
        with lock:
            result = cache.setdefault(key, result)
            cache.move_to_end(key)
            while len(cache) > MAX_ENTRIES:
                cache.popitem(last=False)
        return result

    made.cache_clear = cache.clear  # type: ignore[attr-defined]
    return made  # type: ignore[return-value]
