"""``mbn run programs-vs-dynamics``: new behaviours learned by programs against learned as
dynamics, with the same DE, episodes and budget (``docs/contest.md``).

Stages:

1.–4. ``multiplier``, ``rf``, ``lf_search``, ``lf``: as in ``mbn reproduce`` (the same stage
   keys: for one seed, the same RF and LF).
8. ``im_full``: the fully programmable interpreter of RF, as in ``mbn run new-behaviours``.
14. ``contest``: for each new rule, program search on that interpreter, a new CTRNN from
   scratch and RF re-evolved, each tested every few generations: evaluations to success.
15. ``contest3``: the three-behaviour task, the MBN's route (one new program, a code program
   module) against a monolithic CTRNN that reads the tiles itself.

One run is one sample; ``mbn sweep --experiment programs-vs-dynamics --seeds 0-19`` runs the
seeds and compares the contenders over them (k of N, censored medians, the solved curve, the
ratio of medians, Mann–Whitney U and A12).
"""

from __future__ import annotations

from typing import Any

from mbn.experiments.contest.report import claims, write_report
from mbn.experiments.pipeline import Experiment, Registry, RunConfig, RunDir
from mbn.experiments.stages.compose import PROGRAMS_SHARED
from mbn.experiments.stages.contest import CONTENDERS, ContestStage
from mbn.experiments.stages.contest3 import Contest3Stage
from mbn.experiments.stages.im_full import IMFullStage
from mbn.experiments.stages.lf import LFStage
from mbn.experiments.stages.lf_search import LFSearchStage
from mbn.experiments.stages.multiplier import MultiplierStage
from mbn.experiments.stages.rf import RFStage
from mbn.experiments.stages.settings import QUICK as REPRODUCE_QUICK
from mbn.experiments.stages.settings import derived_seeds
from mbn.experiments.stages.tests3 import Tests3Settings

__all__ = ["CONTENDERS", "PROGRAMS_VS_DYNAMICS", "RUN_KIND", "STAGES"]

RUN_KIND = "mbn.programs-vs-dynamics"

STAGES = Registry(
    [
        MultiplierStage(),
        RFStage(),
        LFSearchStage(),
        LFStage(),
        IMFullStage(),
        ContestStage(),
        Contest3Stage(),
    ]
)

#: The quick preset: the reproduction's, no agreement curve, a short contest.
QUICK: dict[str, dict[str, Any]] = {
    **REPRODUCE_QUICK,
    "im_full": {"curve": False},
    "contest": {"generations": 4, "check_every": 2, "variants": 1},
    "contest3": {"neurons": 4, "pm_generations": 20, "grown_neurons": (4,)},
}


def _results(
    rundir: RunDir, stages: dict[str, dict[str, Any]], config: RunConfig
) -> dict[str, Any]:
    data = stages["contest"]
    three = stages.get("contest3", {"runs": {}, "tests": {}})
    keys = ("solved", "evaluations", "budget", "final_success", "genes")
    contest = {
        rule: {who: {k: d[k] for k in keys} for who, d in by.items()}
        for rule, by in {**data["runs"], **three["runs"]}.items()
    }
    return {
        "tests": {**data["tests"], **three["tests"]},
        "contest": contest,
        # how program search's checks ran (runs before the setting: as networks)
        "program_checks": data.get("program_checks", "network"),
        "claims": claims(stages),
    }


#: The experiment ``mbn run programs-vs-dynamics`` runs.
PROGRAMS_VS_DYNAMICS = Experiment(
    name="programs-vs-dynamics",
    kind=RUN_KIND,
    registry=STAGES,
    shared=(*PROGRAMS_SHARED, Tests3Settings),
    quick=QUICK,
    seeds=derived_seeds,
    results=_results,
    report=write_report,
)
