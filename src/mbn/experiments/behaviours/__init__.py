"""``mbn run new-behaviours``: new behaviours by programs alone (the paper's abstract and its
discussion, beyond its experiment).

Stages:

1.–4. ``multiplier``, ``rf``, ``lf_search``, ``lf``: as in ``mbn reproduce`` (the same stage
   keys: for one seed, the same RF and LF as ``mbn reproduce --seed`` makes).
8. ``im_full``: a fully programmable interpreter of RF (every connection of the follower genome,
   and LF's), simulated by its structure; its tests with RF's and LF's programs, and agreement
   against the number of programmable connections.
9. ``programs``: new rules (straight-right, straight-left) learned by DE over the programs of the
   fixed ``im_full`` interpreter alone (its sha256 checked), each checked through the interpreter
   and as the network it encodes.
10. ``mbn3``: a three-behaviour MBN, a program module evolved with the interpreter fixed that maps
   one-, two- and three-colour tiles to RF's, LF's and straight-right's programs.
11. ``tests3``: the new rules' programs and the three-behaviour MBN on the three-tile mazes, the
   MBN on the paper's mazes, and the interpreter's sha256 in every file checked.
12. ``generalization``: the new rules' programs and the three-behaviour MBN in mazes drawn
   from their family (train, validation and test splits) and on the zero-shot suite
   (``docs/generalization.md``).

Each stage is one module of the stage library, :mod:`mbn.experiments.stages` (the first four
are the reproduction's); ``docs/behaviours.md`` describes them.
"""

from __future__ import annotations

from typing import Any

from mbn.experiments.behaviours.report import claims, write_report
from mbn.experiments.pipeline import Experiment, Registry, RunConfig, RunDir
from mbn.experiments.stages.compose import PROGRAMS_QUICK, PROGRAMS_SHARED
from mbn.experiments.stages.generalization3 import BehavioursGeneralization
from mbn.experiments.stages.im_full import IMFullStage
from mbn.experiments.stages.lf import LFStage
from mbn.experiments.stages.lf_search import LFSearchStage
from mbn.experiments.stages.mbn3 import MBN3Stage
from mbn.experiments.stages.multiplier import MultiplierStage
from mbn.experiments.stages.programs import ProgramsStage
from mbn.experiments.stages.rf import RFStage
from mbn.experiments.stages.settings import (
    QUICK as REPRODUCE_QUICK,
)
from mbn.experiments.stages.settings import derived_seeds
from mbn.experiments.stages.tests3 import Tests3Stage

__all__ = ["NEW_BEHAVIOURS", "RUN_KIND", "STAGES"]

RUN_KIND = "mbn.new-behaviours"

STAGES = Registry(
    [
        MultiplierStage(),
        RFStage(),
        LFSearchStage(),
        LFStage(),
        IMFullStage(),
        ProgramsStage(),
        MBN3Stage(),
        Tests3Stage(),
        BehavioursGeneralization(),
    ]
)

#: The quick preset: the reproduction's, and a short agreement curve.
QUICK: dict[str, dict[str, Any]] = {
    **REPRODUCE_QUICK,
    **PROGRAMS_QUICK,
    "mbn3": {"generations": 30, "maze_generations": 0},
}


def _results(
    rundir: RunDir, stages: dict[str, dict[str, Any]], config: RunConfig
) -> dict[str, Any]:
    return {
        "tests": {**stages["im_full"]["tests"], **stages["tests3"]["tests"]},
        "claims": claims(stages),
    }


#: The experiment ``mbn run new-behaviours`` runs.
NEW_BEHAVIOURS = Experiment(
    name="new-behaviours",
    kind=RUN_KIND,
    registry=STAGES,
    shared=PROGRAMS_SHARED,
    quick=QUICK,
    seeds=derived_seeds,
    results=_results,
    report=write_report,
)
