"""Argument types shared by the ``mbn`` commands: each turns bad text into one argparse error."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = [
    "ALLOW_OTHER_CODE_HELP",
    "REUSE_HELP",
    "int_in",
    "number_in",
    "numbers",
    "positive_float",
    "positive_int",
    "reuse_source",
    "seed",
]

#: ``--reuse DIR`` of ``mbn reproduce`` and ``mbn run``.
REUSE_HELP = (
    "take the stages this experiment shares with the run in DIR (same seed, same settings, "
    "same code) instead of running them again, e.g. RF and LF from another experiment's "
    "run (docs/reproduce.md)"
)

#: ``--allow-other-code`` of ``mbn reproduce``, ``mbn run`` and ``mbn sweep``.
ALLOW_OTHER_CODE_HELP = (
    "resume a run, or take stages from one, that other code made (another commit, uncommitted "
    "changes, another installed version): refused without it; run.json records that it was "
    "given (docs/provenance.md)"
)


def positive_int(text: str) -> int:
    """An integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return value


def seed(text: str) -> int:
    """A seed in [0, 2**32)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if not 0 <= value < 2**32:
        raise argparse.ArgumentTypeError(f"must be in [0, 2**32), got {value}")
    return value


def numbers(text: str, n: int) -> tuple[float, ...]:
    """``n`` comma-separated finite numbers."""
    parts = text.split(",")
    if len(parts) != n:
        raise argparse.ArgumentTypeError(f"expected {n} comma-separated numbers, got {text!r}")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers, got {text!r}") from None
    if not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"numbers must be finite, got {text!r}")
    return values


def int_in(low: int, high: int) -> Callable[[str], int]:
    """An argument type: an integer in ``[low, high]`` (an absurd value is refused in one line
    instead of running out of memory or time)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"must be in [{low}, {high}], got {value}")
        return value

    parse.__name__ = "integer"
    return parse


def number_in(high: float, unit: str = "") -> Callable[[str], float]:
    """An argument type: a finite number in ``(0, high]``."""

    def parse(text: str) -> float:
        value = positive_float(text)
        if value > high:
            raise argparse.ArgumentTypeError(f"must be at most {high:g}{unit}, got {text}")
        return value

    parse.__name__ = "number"
    return parse


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system tells it)."""
    import os

    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def reuse_source(path: Path | None, experiment: Any = None) -> Any:
    """``--reuse DIR`` read (:func:`mbn.experiments.pipeline.reuse.read_source`), or None; the
    source run's experiment is ``experiment`` (the one about to run) where its ``kind`` is the
    source's, else the registered one of that kind."""
    if path is None:
        return None
    from mbn.experiments.pipeline.reuse import read_source
    from mbn.experiments.registry import of_kind

    return read_source(path, lambda kind: of_kind(kind, also=experiment))
