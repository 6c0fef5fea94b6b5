"""What experiments built on the reproduction's controllers compose from: the settings sections
they share and the stages that make the controllers, in order."""

from __future__ import annotations

from mbn.experiments.pipeline import Stage
from mbn.experiments.stages.im import IMStage
from mbn.experiments.stages.lf import LFStage
from mbn.experiments.stages.lf_search import LFSearchStage
from mbn.experiments.stages.multiplier import MultiplierStage
from mbn.experiments.stages.pm import PMStage
from mbn.experiments.stages.rf import RFStage
from mbn.experiments.stages.settings import (
    DESettings,
    EpisodeSettings,
    FollowerSettings,
    InterpreterSettings,
    ValidationSettings,
)
from mbn.world.sensors import NoiseConfig

__all__ = ["SHARED", "controller_stages"]

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
