"""Every stage's random-stream number, in one table: a stage draws from ``fold_in(run key,
KEYS[module])``, keyed by its module in the stage library (a module of several stages:
``MODULE.STAGE``). A number is never moved or used
again (a run's results depend on it); a new stage takes the next one. A stage of a lab's own
experiment, outside the library, takes a number of 100 or more (``OWN_KEYS_FROM``)."""

from __future__ import annotations

__all__ = ["KEYS", "OWN_KEYS_FROM"]

KEYS: dict[str, int] = {
    "multiplier": 1,
    "rf": 2,
    "lf_search": 3,
    "lf": 4,
    "im": 5,
    "pm": 6,
    "tests": 7,
    "im_full": 8,
    "programs": 9,
    "mbn3": 10,
    "tests3": 11,
    "noise_levels": 12,
    "ablations": 13,
    "contest": 14,
    "contest3": 15,
    "generalization": 16,
    "generalization3": 17,
    "interpolation": 18,
    # a module of several stages: MODULE.STAGE
    "scaling.mbn_k2": 19,
    "scaling.mbn_k3": 20,
    "scaling.mbn_k4": 21,
    "scaling.mbn_k5": 22,
    "scaling.mbn_k6": 23,
    "scaling.generalization": 24,
}

#: The first number the stages of experiments outside the library may take.
OWN_KEYS_FROM = 100
