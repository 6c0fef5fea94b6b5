"""Stage ``rf``: the right-follower, 12 genes evolved by DE/best/1/bin on the crossroads
(paper 3.1)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from mbn.config import Settings, setting
from mbn.experiments.evolve import Genome
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.stages.common import evolve_follower
from mbn.experiments.stages.keys import KEYS
from mbn.notation import connection_names

__all__ = ["RFSettings", "RFStage", "evolution_summary"]


@dataclass(frozen=True)
class RFSettings(Settings):
    """The right-follower (RF): all 12 genes (W 3x3, WE on the diagonal) evolved."""

    section = "rf"
    generations: int = setting(
        150,
        doc="DE generations",
        low=0,
        high=100_000,
        source="docs/generalization.md (on maze episodes RF's fitness levels off by about "
        "generation 40); the paper's protocol: 300 (docs/configs/paper.toml)",
    )
    variants: int = setting(
        4,
        doc="starts per crossroad: the mark and variants - 1 jittered ones",
        low=1,
        high=100,
        source="docs/experiments.md (the paper: one start per crossroad)",
    )
    restarts: int = setting(
        2,
        doc="independent DE runs, evolved until this many pass the validation maze; the "
        "fittest of those is kept",
        low=1,
        high=100,
        source="docs/reproduce.md; docs/speed.md (1 was tried: it changed the RF of seeds 1 "
        "and 3 and cost them rounds)",
    )


def evolution_summary(
    data: dict[str, Any], connections: bool = False, label: str = "best fitness", fmt: str = ".2f"
) -> str:
    """``best fitness F after G generations`` (``label``, F in ``fmt``; and the connections
    evolved, and the success on the validation maze)."""
    extra = f" ({connection_names(data['connections'])})" if connections else ""
    v = data.get("validation")
    check = f"; validation {v['successes']}/{v['trials']}" if v else ""
    return (
        f"{label} {data['best_fitness']:{fmt}} after {data['generations']} generations"
        f"{extra}{check}"
    )


class RFStage(Stage):
    name = "rf"
    key_id = KEYS["rf"]
    outputs = ("controllers/rf.json",)
    settings = RFSettings

    def run(self, ctx: StageContext) -> dict[str, Any]:
        s: RFSettings = ctx.settings
        data = evolve_follower(
            ctx, Genome(), "right", s.variants, s.generations, restarts=s.restarts, validated=True
        )
        data.pop("network")
        return data

    def summary(self, data: dict[str, Any]) -> str:
        return evolution_summary(data)
