"""``mbn run scaling``: MBNs of 2 to 6 behaviours on one fixed interpreter (``docs/scaling.md``).

Stages:

1.–4., 8.–9. ``multiplier``, ``rf``, ``lf_search``, ``lf``, ``im_full``, ``programs``: as in
   ``mbn run new-behaviours`` (the same stage keys), with programs for the four rules beyond
   RF's and LF's (straight-right, straight-left, right-left, left-right).
19.–23. ``mbn_k2`` .. ``mbn_k6``: the MBN of K behaviours, grown from the one before by a tile
   kind, a program module neuron and a readout column, the interpreter hash-checked.
24. ``generalization``: each MBN on its tile family's test split, and on the one before's
   (forgetting).
"""

from __future__ import annotations

from typing import Any

from mbn.experiments.pipeline import Experiment, Registry, RunConfig, RunDir
from mbn.experiments.scaling.report import claims, scaling_summary, write_report
from mbn.experiments.stages.compose import PROGRAMS_QUICK, PROGRAMS_SHARED, program_stages
from mbn.experiments.stages.scaling import (
    SCALING_RULES,
    ScalingGeneralization,
    ScalingSettings,
    scaling_stages,
)
from mbn.experiments.stages.settings import QUICK as REPRODUCE_QUICK
from mbn.experiments.stages.settings import derived_seeds

__all__ = ["RUN_KIND", "SCALING", "STAGES"]

RUN_KIND = "mbn.scaling"

STAGES = Registry(
    [
        *program_stages(),
        *scaling_stages(),
        ScalingGeneralization(),
    ]
)

#: Programs for every rule past RF's and LF's; each MBN judged on test splits only (the
#: train and validation columns of the generalization gap are the new-behaviours run's).
DEFAULTS: dict[str, dict[str, Any]] = {
    "programs": {"rules": SCALING_RULES[2:]},
    "generalization": {"splits": ("test", "zero-shot"), "gap_mazes": 0},
}

#: The quick preset: the new behaviours' quick run, short program modules, few test mazes.
QUICK: dict[str, dict[str, Any]] = {
    **REPRODUCE_QUICK,
    **PROGRAMS_QUICK,
    "scaling": {"generations": 30, "maze_generations": 0},
    "generalization": {
        **REPRODUCE_QUICK["generalization"],
        "test_mazes": 2,
        "gap_mazes": 0,
        "splits": ("test",),
    },
}


def _results(
    rundir: RunDir, stages: dict[str, dict[str, Any]], config: RunConfig
) -> dict[str, Any]:
    return {"scaling": scaling_summary(stages), "claims": claims(stages)}


#: The experiment ``mbn run scaling`` runs.
SCALING = Experiment(
    name="scaling",
    kind=RUN_KIND,
    registry=STAGES,
    shared=(*PROGRAMS_SHARED, ScalingSettings),
    defaults=DEFAULTS,
    quick=QUICK,
    seeds=derived_seeds,
    results=_results,
    report=write_report,
)
