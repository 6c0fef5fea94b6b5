"""``mbn run ablations``: the MBN with parts of its program path changed, one at a time.

Stages:

1.–6. ``multiplier``, ``rf``, ``lf_search``, ``lf``, ``im``, ``pm``: as in ``mbn reproduce``
   (the same stage keys: for one seed, the same controllers as ``mbn reproduce --seed``).
13. ``ablations``: the wrong program, the program frozen, exact products, the multipliers'
   time constant at τ/5 to τ/50, the 3-neuron multiplier (``docs/ablations.md``).
"""

from __future__ import annotations

from typing import Any

from mbn.experiments.ablations.report import claims, write_report
from mbn.experiments.ablations.stages.program_path import AblationsStage
from mbn.experiments.pipeline import Experiment, Registry, RunConfig, RunDir
from mbn.experiments.reproduce import SHARED, controller_stages
from mbn.experiments.reproduce.settings import QUICK as REPRODUCE_QUICK
from mbn.experiments.reproduce.settings import derived_seeds
from mbn.experiments.reproduce.stages.tests import TestsSettings

__all__ = ["ABLATIONS", "RUN_KIND", "STAGES"]

RUN_KIND = "mbn.ablations"

STAGES = Registry([*controller_stages(), AblationsStage()])

#: The quick preset: the reproduction's, and few trials.
QUICK: dict[str, dict[str, Any]] = {
    **REPRODUCE_QUICK,
    "ablations": {"jitter_per_mark": 1, "heldout_repeats": 1},
}


def _results(
    rundir: RunDir, stages: dict[str, dict[str, Any]], config: RunConfig
) -> dict[str, Any]:
    return {"variants": stages["ablations"]["variants"], "claims": claims(stages)}


#: The experiment ``mbn run ablations`` runs.
ABLATIONS = Experiment(
    name="ablations",
    kind=RUN_KIND,
    registry=STAGES,
    shared=(*SHARED, TestsSettings),
    quick=QUICK,
    seeds=derived_seeds,
    results=_results,
    report=write_report,
)
