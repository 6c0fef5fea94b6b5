"""Judging a controller across many mazes at once: a split of a maze family, the zero-shot
suite (``docs/generalization.md``).

:func:`evaluate_mazes` runs every maze's trials in one batched rollout under one time limit (the
longest of the mazes' own, unless given) and gives one row per maze and the pooled figures;
``mbn evaluate --maze FAMILY/SPLIT`` prints it, and the runs' generalization sections are made
of it.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from jax import Array

from mbn.experiments.trials import TrialGroup, TrialSpec, route_seconds, run_trial_groups, summary

__all__ = ["MAZE_TARGET", "evaluate_mazes", "pooled_rows"]

#: A maze counts as passed when at least this share of its trials succeed (the tests' target).
MAZE_TARGET = 0.95


def pooled_rows(rows: list[dict[str, Any]], target: float = MAZE_TARGET) -> dict[str, Any]:
    """The pooled trials, successes, time-outs and rate of per-maze rows, and how many of the
    mazes reach ``target``."""
    pooled: dict[str, Any] = {
        k: int(sum(r[k] for r in rows)) for k in ("trials", "successes", "timed_out")
    }
    pooled["success_rate"] = pooled["successes"] / pooled["trials"] if pooled["trials"] else 0.0
    at = sum(r["success_rate"] >= target for r in rows)
    return {
        "pooled": pooled,
        "mazes_at_95": int(at),
        "fraction_of_mazes_at_95": at / len(rows) if rows else 0.0,
    }


def evaluate_mazes(
    mazes: list[Any],
    spec: TrialSpec,
    loaded: Any,
    *,
    seconds: float | None = None,
    key: Array | None = None,
    verdicts: bool = False,
) -> dict[str, Any]:
    """Every maze's trials of ``spec`` for the loaded controller ``loaded``, in one batch.

    Returns ``{"mazes": [{"maze", ...summary}], "pooled", "mazes_at_95",
    "fraction_of_mazes_at_95", "seconds"}`` (and, ``verdicts``, each maze's verdict arrays under
    ``"verdicts"``, by maze name, not JSON). ``seconds``: the time limit (default the longest of
    the mazes' own, :func:`~mbn.experiments.trials.route_seconds`); ``key``: the noise's key
    (when the controller runs under noise)."""
    if not mazes:
        raise ValueError("evaluate_mazes needs at least one maze")
    names = [m.name for m in mazes]
    if len(set(names)) != len(names):
        raise ValueError("evaluate_mazes needs mazes of distinct names")
    if seconds is None:
        seconds = max(route_seconds(m, spec) for m in mazes)
    spec = dataclasses.replace(spec, seconds=seconds)
    camera = loaded.camera
    if camera is None and spec.behavior == "tiles":
        from mbn.world.engine import CameraConfig

        camera = CameraConfig()
    out, _, _, _ = run_trial_groups(
        mazes,
        [TrialGroup(m.name, i, spec, loaded.initial_state) for i, m in enumerate(mazes)],
        loaded.controller,
        seconds=seconds,
        dt=loaded.dt,
        sensors=loaded.sensors,
        camera=camera,
        noise=loaded.noise,
        key=key,
    )
    rows = [{"maze": m.name, **summary(out[m.name])} for m in mazes]
    result: dict[str, Any] = {"mazes": rows, **pooled_rows(rows), "seconds": float(seconds)}
    if verdicts:
        result["verdicts"] = {n: {k: np.asarray(v) for k, v in out[n].items()} for n in names}
    return result
