"""What experiments built on the reproduction's controllers compose from: the settings sections
they share and the stages that make the controllers, in order."""

from __future__ import annotations

from typing import Any

from mbn.experiments.pipeline import Stage
from mbn.experiments.stages.im import IMStage
from mbn.experiments.stages.im_full import IMFullStage
from mbn.experiments.stages.lf import LFStage
from mbn.experiments.stages.lf_search import LFSearchStage
from mbn.experiments.stages.multiplier import MultiplierStage
from mbn.experiments.stages.pm import PMStage
from mbn.experiments.stages.programs import ProgramsStage
from mbn.experiments.stages.rf import RFStage
from mbn.experiments.stages.settings import (
    DESettings,
    EpisodeSettings,
    FollowerSettings,
    InterpreterSettings,
    ValidationSettings,
)
from mbn.experiments.stages.tests import TestsSettings
from mbn.world.sensors import NoiseConfig

__all__ = ["PROGRAMS_QUICK", "PROGRAMS_SHARED", "SHARED", "controller_stages", "program_stages"]

#: The sections every experiment built on the reproduction's controllers shares.
SHARED = (
    DESettings,
    FollowerSettings,
    EpisodeSettings,
    InterpreterSettings,
    ValidationSettings,
    NoiseConfig,
)


def controller_stages() -> list[Stage]:
    """The stages that make the reproduction's controllers (multiplier to PM), in order: an
    experiment that studies them runs these with the same stage keys, so that for one seed
    they are ``mbn reproduce --seed``'s."""
    return [MultiplierStage(), RFStage(), LFSearchStage(), LFStage(), IMStage(), PMStage()]


def program_stages() -> list[Stage]:
    """The stages that make the fully programmable interpreter and its programs (multiplier,
    RF, the LF search, LF, ``im_full``, ``programs``), in order: an experiment that studies the
    programs runs these with the same stage keys, so that for one seed they are ``mbn run
    new-behaviours``'s (and ``--reuse`` takes them from it)."""
    return [
        MultiplierStage(),
        RFStage(),
        LFSearchStage(),
        LFStage(),
        IMFullStage(),
        ProgramsStage(),
    ]


#: What the quick preset of such an experiment sets beyond the reproduction's: no agreement
#: curve, short program searches.
PROGRAMS_QUICK: dict[str, dict[str, Any]] = {
    "im_full": {"curve": False},
    "programs": {"generations": 10, "variants": 1},
}

#: The sections every experiment built on the programs shares (no run noise: the new-behaviours
#: experiment and those that take its stages).
PROGRAMS_SHARED = (
    DESettings,
    FollowerSettings,
    EpisodeSettings,
    InterpreterSettings,
    ValidationSettings,
    TestsSettings,
)
