"""``mbn reproduce``: the paper's whole experiment, stage by stage, checkpointed and resumable.

Stages (paper section 3; ``docs/reproduce.md`` describes each and every deviation):

1. ``multiplier``: the shipped multiplier (6 neurons by default) or one trained again.
2. ``rf``: the right-follower, 12 genes evolved by DE/best/1/bin on the crossroads.
3. ``lf_search``: which 3 connections of RF to re-evolve for the left-follower.
4. ``lf``: those 3 connections re-evolved at length.
5. ``im``: the interpreter of RF with the connections that differ between RF and LF programmable,
   and the RF and LF programs.
6. ``pm``: the program module, evolved with the interpreter fixed.
7. ``tests``: the paper's protocol, jittered starts and the held-out maze, for RF, LF, the
   interpreter with each program, the MBN and the published weights.
8. ``generalization``: the same controllers in mazes drawn from their family (train,
   validation and test splits) and on the zero-shot suite (``docs/generalization.md``).

Each stage is one module of the stage library, :mod:`mbn.experiments.stages`; :data:`STAGES`
lists them in order (adding a stage: one module there and one line here). The run folder, resume and
``results.json`` are :mod:`mbn.experiments.pipeline`'s; the claims table and the report are
built from the run folder.
"""

from __future__ import annotations

from typing import Any

from mbn.experiments.pipeline import Experiment, Registry, RunConfig, RunDir
from mbn.experiments.reproduce.claims import claims
from mbn.experiments.reproduce.report import write_report
from mbn.experiments.stages.compose import SHARED, controller_stages
from mbn.experiments.stages.generalization import ReproduceGeneralization
from mbn.experiments.stages.lf import LFStage
from mbn.experiments.stages.multiplier import MultiplierStage
from mbn.experiments.stages.settings import QUICK, derived_seeds
from mbn.experiments.stages.tests import TestsSettings, TestsStage

__all__ = ["REPRODUCE", "RUN_KIND", "STAGES"]

RUN_KIND = "mbn.reproduce"


#: The stages of the paper's experiment, in the order they run.
STAGES = Registry([*controller_stages(), TestsStage(), ReproduceGeneralization()])


def _results(
    rundir: RunDir, stages: dict[str, dict[str, Any]], config: RunConfig
) -> dict[str, Any]:
    """The tests and the claims table of ``results.json``."""
    tested = TestsStage.from_json(stages[TestsStage.name])
    table = claims(
        MultiplierStage.from_json(stages[MultiplierStage.name]),
        tested,
        LFStage.from_json(stages[LFStage.name]).connections,
        stages.get(ReproduceGeneralization.name),
        config.get(TestsSettings),
    )
    return {"tests": stages[TestsStage.name]["tests"], "claims": table}


#: The experiment ``mbn reproduce`` runs.
REPRODUCE = Experiment(
    name="reproduce",
    kind=RUN_KIND,
    registry=STAGES,
    shared=SHARED,
    quick=QUICK,
    seeds=derived_seeds,
    results=_results,
    report=write_report,
)
