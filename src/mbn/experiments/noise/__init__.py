"""``mbn run noise``: what survives noise (the paper's section 4 doubts its robustness).

Stages:

1.–6. ``multiplier``, ``rf``, ``lf_search``, ``lf``, ``im``, ``pm``: as in ``mbn reproduce``
   (the same stage keys: for one seed, the same controllers as ``mbn reproduce --seed``).
12. ``noise_levels``: RF, the interpreter with RF's and LF's programs and the MBN, on the
   jittered test and the held-out maze, with each channel of the noise model alone at
   increasing levels and all at once at a realistic level (``docs/noise.md``).
"""

from __future__ import annotations

from typing import Any

from mbn.experiments.noise.over_runs import noise_tests
from mbn.experiments.noise.report import claims, write_report
from mbn.experiments.pipeline import Experiment, Registry, RunConfig, RunDir
from mbn.experiments.stages.compose import SHARED, controller_stages
from mbn.experiments.stages.noise_levels import NoiseLevelsStage
from mbn.experiments.stages.settings import QUICK as REPRODUCE_QUICK
from mbn.experiments.stages.settings import derived_seeds
from mbn.experiments.stages.tests import TestsSettings

__all__ = ["NOISE", "RUN_KIND", "STAGES"]

RUN_KIND = "mbn.noise"

STAGES = Registry([*controller_stages(), NoiseLevelsStage()])

#: The quick preset: the reproduction's, two channels at one level each, few trials.
QUICK: dict[str, dict[str, Any]] = {
    **REPRODUCE_QUICK,
    "noise_levels": {
        "channels": ["sonar_dropout", "program_std"],
        "sonar_dropout": [0.0, 0.2],
        "program_std": [0.0, 0.1],
        "jitter_per_mark": 1,
        "heldout_repeats": 1,
    },
}


def _results(
    rundir: RunDir, stages: dict[str, dict[str, Any]], config: RunConfig
) -> dict[str, Any]:
    data = stages["noise_levels"]
    return {
        "realistic": data["realistic"],
        "channels": data["channels"],
        "levels": data["levels"],
        "tests": noise_tests(data),
        "claims": claims(stages),
    }


#: The experiment ``mbn run noise`` runs.
NOISE = Experiment(
    name="noise",
    kind=RUN_KIND,
    registry=STAGES,
    shared=(*SHARED, TestsSettings),
    quick=QUICK,
    seeds=derived_seeds,
    results=_results,
    report=write_report,
)
