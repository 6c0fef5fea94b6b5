"""Stage ``lf``: the left-follower, the 3 connections chosen by ``lf_search`` re-evolved at
length from that triple's final search population (paper 3.1). The LF and the interpreter
running its program are checked on the validation maze; if either falls short, another
candidate is evolved — first on the rf stage's other RF (its triples searched then), then the
next (RF, triple) by the search's score — up to ``[validation] attempts`` in all, and the best
kept. An LF built on another RF makes that RF the run's (``controllers/rf.json``)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from mbn.config import Settings, setting
from mbn.controllers import CTRNNControllerSpec, InterpreterControllerSpec
from mbn.errors import MbnInputError
from mbn.experiments.evolve import Genome
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.reproduce.stages.common import (
    SCORE_KEYS,
    evolve_follower,
    restart_rank,
    save_follower,
    score,
    validate,
)
from mbn.experiments.reproduce.stages.lf_search import (
    best_triple,
    search_checkpoint,
    search_triples,
)
from mbn.experiments.reproduce.stages.rf import evolution_summary
from mbn.networks.multiplier import load_multiplier
from mbn.networks.programmable import Connection, build_interpreter, differing_connections
from mbn.world.mazes.builtin import APPROACHES, check_approaches

__all__ = ["ATTEMPT_KEY", "LFSettings", "LFStage"]

#: Folded (plus the attempt's number) into the stage's key for each further LF attempt.
ATTEMPT_KEY = 100
#: Folded (plus the restart's number) into the stage's key for the triple search of another RF.
RF_SEARCH_KEY = 1000


def _restart_checkpoint(restart: int) -> Callable[[int], str]:
    return lambda t: f"lf_search_rf{restart}_{t:02d}"


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
        rf_data = ctx.read("rf")
        mul = load_multiplier(ctx.rundir.controller_file("multiplier"))
        # The RF candidates: the rf stage's restarts, the one it kept first, then the others
        # that met the validation target, by its own ranking. A restart's triples are searched
        # only when an attempt needs them.
        kept = int(rf_data.get("chosen_restart", 0))
        restarts = rf_data.get("restarts") or [rf_data]
        others = [
            r
            for r in sorted(
                range(len(restarts)), key=lambda i: restart_rank(restarts[i], i), reverse=True
            )
            if r != kept and restarts[r].get("validation", {}).get("meets_target", True)
        ]
        # the RFs from the rf stage's record, not controllers/rf.json, which this stage may
        # have rewritten before an interruption
        rfs = {kept: Genome().network(jnp.asarray(restarts[kept]["best_genome"]))}
        searched: dict[int, tuple[list[dict[str, Any]], Callable[[int], str]]] = {
            kept: (search["triples"], search_checkpoint)
        }
        used: set[tuple[int, int]] = set()
        attempts: list[dict[str, Any]] = []
        for a in range(ctx.section("validation").attempts):
            if a == 0:
                r, t = kept, int(search["chosen_index"])
            elif a == 1 and others:
                r = others[0]
                rfs[r] = Genome().network(jnp.asarray(restarts[r]["best_genome"]))
                checkpoint = _restart_checkpoint(r)
                key = jax.random.fold_in(ctx.key, RF_SEARCH_KEY + r)
                searched[r] = (search_triples(ctx, rfs[r], key, checkpoint), checkpoint)
                t = best_triple(searched[r][0])
            else:
                free = [(q, i) for q in searched for i in range(len(searched[q][0]))]
                free = [c for c in free if c not in used]
                if not free:
                    break
                r, t = max(free, key=lambda c: (searched[c[0]][0][c[1]]["robust_fitness"], -c[1]))
            used.add((r, t))
            rows, checkpoint = searched[r]
            attempts.append(self._attempt(ctx, s, a, rfs[r], r, rows[t], checkpoint(t), mul))
            d = attempts[-1]["data"]
            if d["validation"]["meets_target"] and d["validation_im"]["meets_target"]:
                break

        def rank(i: int) -> tuple[float, float, int]:
            d = attempts[i]["data"]
            worst = min(d["validation"]["success_rate"], d["validation_im"]["success_rate"])
            return (worst, d["best_fitness"], -i)

        chosen = max(range(len(attempts)), key=rank)
        best = attempts[chosen]
        data = dict(best["data"])
        save_follower(
            ctx, "lf", best["net"], "left", data["connections"], {k: data[k] for k in SCORE_KEYS}
        )
        if best["rf_restart"] != kept:
            # The LF was built on another RF: that RF is the run's (the interpreter, the
            # program module and the tests read controllers/rf.json).
            rf = rfs[best["rf_restart"]]
            rf_settings = ctx.section("rf")
            scored = score(ctx, rf, "right", rf_settings.variants)
            save_follower(ctx, "rf", rf, "right", [str(c) for c in Genome().connections], scored)
        data["rf_restart"] = best["rf_restart"]
        data["rf_switched"] = best["rf_restart"] != kept
        data["attempts"] = [
            {
                "rf_restart": x["rf_restart"],
                "connections": x["data"]["connections"],
                "best_fitness": x["data"]["best_fitness"],
                "validation": x["data"]["validation"],
                "validation_im": x["data"]["validation_im"],
            }
            for x in attempts
        ]
        data["chosen_attempt"] = chosen
        return data

    def _attempt(
        self,
        ctx: StageContext,
        s: LFSettings,
        a: int,
        rf: Any,
        restart: int,
        row: dict[str, Any],
        checkpoint: str,
        mul: Any,
    ) -> dict[str, Any]:
        """LF re-evolved on ``rf`` from one triple's search population, then checked alone
        and as the interpreter's program on the validation maze."""
        conns = tuple(Connection.parse(c) for c in row["connections"])
        genome = Genome.around(rf, conns)
        start = ctx.rundir.load_checkpoint(checkpoint)  # warm start: the search population
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
        data["validation"] = validate(ctx, CTRNNControllerSpec(net=net, behavior="left"), "left")
        # The interpreter built on RF with this LF, running LF's program: an LF whose behaviour
        # the multipliers' small errors break fails here.
        interp = build_interpreter(rf, differing_connections(rf, net, margin=0.0), mul)
        im = InterpreterControllerSpec(
            interpreter=interp,
            programs={"left": np.asarray(interp.program_of(net), dtype=float).tolist()},
        )
        data["validation_im"] = validate(ctx, im, "left", "left")
        return {"data": data, "net": net, "rf_restart": restart}

    def summary(self, data: dict[str, Any]) -> str:
        return evolution_summary(data, connections=True)
