"""Stage ``lf``: the left-follower, the 3 connections chosen by ``lf_search`` re-evolved at
length from that triple's final search population (paper 3.1). The LF and the interpreter
running its program are checked on the validation maze; if either falls short, the next triple
by the search's score is evolved, up to ``[validation] attempts`` in all, and the best kept."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import jax
import numpy as np

from mbn.config import Settings, setting
from mbn.controllers import CTRNNControllerSpec, InterpreterControllerSpec
from mbn.errors import MbnInputError
from mbn.experiments.evolve import Genome
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.reproduce.stages.common import (
    evolve_follower,
    read_network,
    save_follower,
    validate,
)
from mbn.experiments.reproduce.stages.lf_search import search_checkpoint
from mbn.experiments.reproduce.stages.rf import evolution_summary
from mbn.networks.multiplier import load_multiplier
from mbn.networks.programmable import Connection, build_interpreter, differing_connections
from mbn.world.mazes.builtin import APPROACHES, check_approaches

__all__ = ["ATTEMPT_KEY", "LFSettings", "LFStage"]

#: Folded (plus the attempt's number) into the stage's key for each further LF attempt.
ATTEMPT_KEY = 100


def _scored(data: dict[str, Any]) -> dict[str, Any]:
    return {
        k: data[k] for k in ("branch_fitness", "episodes", "paper_F_M", "paper_F_R", "paper_F_L")
    }


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
    needs = ("multiplier", "rf", "lf_search")
    settings = LFSettings

    def run(self, ctx: StageContext) -> dict[str, Any]:
        s: LFSettings = ctx.settings
        search = ctx.read("lf_search")
        rf = read_network(ctx, "rf")
        mul = load_multiplier(ctx.rundir.controller_file("multiplier"))
        rows = search["triples"]
        # The search's choice first, then the next triples by the same score.
        order = sorted(range(len(rows)), key=lambda i: (-rows[i]["robust_fitness"], i))
        order.remove(search["chosen_index"])
        order.insert(0, search["chosen_index"])
        attempts: list[dict[str, Any]] = []
        for a, t in enumerate(order[: ctx.section("validation").attempts]):
            conns = tuple(Connection.parse(c) for c in rows[t]["connections"])
            genome = Genome.around(rf, conns)
            # Warm start: the triple's final search population.
            start = ctx.rundir.load_checkpoint(search_checkpoint(t))
            data = evolve_follower(
                ctx,
                genome,
                "left",
                s.variants,
                s.generations,
                np.asarray(start.state.population),
                s.approaches,
                name="lf" if a == 0 else f"lf_attempt{a}",
                key=ctx.key if a == 0 else jax.random.fold_in(ctx.key, ATTEMPT_KEY + a),
                save=False,
            )
            net = data.pop("network")
            data["connections_paper_notation"] = [c.paper_name for c in conns]
            data["validation"] = validate(
                ctx, CTRNNControllerSpec(net=net, behavior="left"), "left"
            )
            # The interpreter built on RF with this LF, running LF's program: an LF whose
            # behaviour the multipliers' small errors break fails here.
            interp = build_interpreter(rf, differing_connections(rf, net, margin=0.0), mul)
            im = InterpreterControllerSpec(
                interpreter=interp,
                programs={"left": np.asarray(interp.program_of(net), dtype=float).tolist()},
            )
            data["validation_im"] = validate(ctx, im, "left", "left")
            attempts.append({"data": data, "net": net, "genome": genome})
            if data["validation"]["meets_target"] and data["validation_im"]["meets_target"]:
                break

        def rank(i: int) -> tuple[float, float, int]:
            d = attempts[i]["data"]
            worst = min(d["validation"]["success_rate"], d["validation_im"]["success_rate"])
            return (worst, d["best_fitness"], -i)

        chosen = max(range(len(attempts)), key=rank)
        best = attempts[chosen]
        data = dict(best["data"])
        save_follower(ctx, "lf", best["net"], "left", data["connections"], _scored(data))
        data["attempts"] = [
            {
                "connections": a["data"]["connections"],
                "best_fitness": a["data"]["best_fitness"],
                "validation": a["data"]["validation"],
                "validation_im": a["data"]["validation_im"],
            }
            for a in attempts
        ]
        data["chosen_attempt"] = chosen
        return data

    def summary(self, data: dict[str, Any]) -> str:
        return evolution_summary(data, connections=True)
