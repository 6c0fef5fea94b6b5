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
from mbn.experiments.pipeline import Experiment, Registry, RunConfig, RunDir
from mbn.experiments.stages.ablations import AblationsStage
from mbn.experiments.stages.compose import SHARED, controller_stages
from mbn.experiments.stages.settings import QUICK as REPRODUCE_QUICK
from mbn.experiments.stages.settings import derived_seeds
from mbn.experiments.stages.tests import TestsSettings
from mbn.experiments.trials import as_test_record

__all__ = ["ABLATIONS", "RUN_KIND", "STAGES", "ablation_tests"]

RUN_KIND = "mbn.ablations"

STAGES = Registry([*controller_stages(), AblationsStage()])

#: The quick preset: the reproduction's, and few trials.
QUICK: dict[str, dict[str, Any]] = {
    **REPRODUCE_QUICK,
    "ablations": {"jitter_per_mark": 1, "heldout_repeats": 1},
}


def ablation_tests(variants: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The ablations' trials as tests, the way ``results.json`` records them for a sweep: per
    variant ``V``, the MBN's ``V_mbn_jitter`` and ``V_mbn_heldout`` and, where the interpreter
    changes, its ``V_im_rf_jitter`` and ``V_im_lf_jitter`` (``trials``, ``successes``,
    ``success_rate``)."""
    tests: dict[str, dict[str, Any]] = {}
    for variant, row in variants.items():
        for part in ("mbn_jitter", "mbn_heldout", "im_rf_jitter", "im_lf_jitter"):
            if part in row:
                tests[f"{variant}_{part}"] = as_test_record(row[part])
    return tests


def _results(
    rundir: RunDir, stages: dict[str, dict[str, Any]], config: RunConfig
) -> dict[str, Any]:
    variants = stages["ablations"]["variants"]
    return {"variants": variants, "tests": ablation_tests(variants), "claims": claims(stages)}


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
