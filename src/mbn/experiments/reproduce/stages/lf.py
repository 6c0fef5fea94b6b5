"""Stage ``lf``: the left-follower, the 3 connections chosen by ``lf_search`` re-evolved at
length from that triple's final search population (paper 3.1)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from mbn.config import Settings, setting
from mbn.errors import MbnInputError
from mbn.experiments.evolve import Genome
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.reproduce.stages.common import evolve_follower, read_network
from mbn.experiments.reproduce.stages.lf_search import search_checkpoint
from mbn.experiments.reproduce.stages.rf import evolution_summary
from mbn.networks.programmable import Connection
from mbn.world.mazes.builtin import APPROACHES, check_approaches

__all__ = ["LFSettings", "LFStage"]


@dataclass(frozen=True)
class LFSettings(Settings):
    """The left-follower (LF): 3 connections of RF re-evolved."""

    section = "lf"
    generations: int = setting(
        200, doc="DE generations", low=0, high=100_000, source="docs/reproduce.md"
    )
    variants: int = setting(
        4, doc="starts per crossroad", low=1, high=100, source="docs/experiments.md"
    )
    approaches: tuple[str, ...] = setting(
        ("south", "west", "east"),
        doc="how the robot enters the crossroads (the LF search chooses on them too)",
        choices=APPROACHES,
        source="docs/reproduce.md (crossroads entered round a corner, as in a maze)",
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        try:
            check_approaches(self.approaches)
        except MbnInputError as exc:
            raise MbnInputError(f"lf.{exc}") from None


class LFStage(Stage):
    name = "lf"
    key_id = 4
    outputs = ("controllers/lf.json",)
    needs = ("rf", "lf_search")
    settings = LFSettings

    def run(self, ctx: StageContext) -> dict[str, Any]:
        s: LFSettings = ctx.settings
        search = ctx.read("lf_search")
        conns = tuple(Connection.parse(c) for c in search["chosen"])
        genome = Genome.around(read_network(ctx, "rf"), conns)
        # Warm start: the chosen triple's final search population.
        start = ctx.rundir.load_checkpoint(search_checkpoint(search["chosen_index"]))
        data = evolve_follower(
            ctx,
            genome,
            "left",
            s.variants,
            s.generations,
            np.asarray(start.state.population),
            s.approaches,
        )
        data["connections_paper_notation"] = [c.paper_name for c in conns]
        return data

    def summary(self, data: dict[str, Any]) -> str:
        return evolution_summary(data, connections=True)
