"""Stage ``generalization`` of ``mbn run new-behaviours``: the new rules' programs through the
fixed full interpreter and the three-behaviour MBN in mazes drawn from their family (train,
validation, test splits) and on the zero-shot suite (as ``mbn reproduce``'s stage:
:mod:`mbn.experiments.stages.generalization`)."""

from __future__ import annotations

from mbn.experiments.pipeline import StageContext
from mbn.experiments.stages.generalization import GeneralizationStage, Judged
from mbn.experiments.stages.keys import KEYS
from mbn.experiments.stages.programs import ProgramsSettings
from mbn.world.rules import parse_rule

__all__ = ["BehavioursGeneralization"]


class BehavioursGeneralization(GeneralizationStage):
    """The programs of ``[programs] rules`` (run by ``im_full_programs.json``) and the
    three-behaviour MBN (``mbn3.json``), in ``tiles3`` and, beside the two-behaviour MBN of
    ``mbn reproduce`` (forgetting), in ``tiles2``."""

    key_id = KEYS["generalization3"]
    needs = ("programs", "mbn3")

    def controllers(self, ctx: StageContext) -> tuple[Judged, ...]:
        rules = [parse_rule(r).name for r in ctx.section(ProgramsSettings).rules]
        return (
            *(Judged(r.replace("-", "_"), "im_full_programs", r, r) for r in rules),
            Judged("mbn3", "mbn3", "tiles"),
            # the paper's two tiles: what adding the third behaviour costs the first two
            Judged("mbn3_tiles2", "mbn3", "tiles", family="tiles2"),
        )
