"""``mbn run switch``: the switch between programs, looked into (``docs/switch.md``).

Stages:

1.–4., 8.–9. ``multiplier``, ``rf``, ``lf_search``, ``lf``, ``im_full``, ``programs``: as in
   ``mbn run new-behaviours`` (the same stage keys: for one seed, the same controllers; take them
   from a run of it with ``--reuse``).
18. ``interpolation``: the interpreter running alpha P1 + (1 - alpha) P2 for pairs of its
   programs, in mazes of the validation split: where the behaviour changes and how sharply, and
   the equilibria of the network each program decodes to.
"""

from __future__ import annotations

from typing import Any

from mbn.experiments.pipeline import Experiment, Registry, RunConfig, RunDir
from mbn.experiments.stages.compose import PROGRAMS_QUICK, PROGRAMS_SHARED, program_stages
from mbn.experiments.stages.interpolation import InterpolationStage
from mbn.experiments.stages.settings import QUICK as REPRODUCE_QUICK
from mbn.experiments.stages.settings import derived_seeds
from mbn.experiments.switch.over_runs import brief
from mbn.experiments.switch.report import claims, write_report

__all__ = ["RUN_KIND", "STAGES", "SWITCH"]

RUN_KIND = "mbn.switch"

#: The new-behaviours experiment's stages up to the programs, then the sweep.
STAGES = Registry(
    [
        *program_stages(),
        InterpolationStage(),
    ]
)

#: The quick preset: the new behaviours' quick run, three alphas in one maze.
QUICK: dict[str, dict[str, Any]] = {
    **REPRODUCE_QUICK,
    **PROGRAMS_QUICK,
    "interpolation": {"steps": 3, "mazes": 1, "pairs": ("right:left",)},
}


def _results(
    rundir: RunDir, stages: dict[str, dict[str, Any]], config: RunConfig
) -> dict[str, Any]:
    data = InterpolationStage.from_json(stages[InterpolationStage.name])
    return {"pairs": brief(data), "claims": claims(stages)}


#: The experiment ``mbn run switch`` runs.
SWITCH = Experiment(
    name="switch",
    kind=RUN_KIND,
    registry=STAGES,
    shared=PROGRAMS_SHARED,
    quick=QUICK,
    seeds=derived_seeds,
    results=_results,
    report=write_report,
)
