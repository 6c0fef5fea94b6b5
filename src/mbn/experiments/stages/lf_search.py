"""Stage ``lf_search``: which 3 connections of RF to re-evolve for the left-follower. Every triple
of the candidate connections (those into the turning neuron) is evolved briefly; the triple whose
final population holds the best genome *under weight perturbations*, on crossroads entered round
a corner too, is kept (paper 3.1 re-evolves 3 connections; it does not say which or how they were
chosen: docs/reproduce.md)."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import jax
import numpy as np

from mbn.config import Settings, setting
from mbn.errors import MbnInputError
from mbn.experiments.evolve import (
    connection_group_fitness,
    join_rows,
    robust_fitness,
    split_fitness,
)
from mbn.experiments.named import follower_connections
from mbn.experiments.pipeline import DERun, Stage, StageContext
from mbn.experiments.pipeline.results import Record
from mbn.experiments.stages.common import (
    SCORING_DRAW,
    de_config,
    maze_episodes,
    read_network,
    stage_perturbations,
    training_fitness,
    training_task,
)
from mbn.experiments.stages.keys import KEYS
from mbn.experiments.stages.records import Perturbation
from mbn.experiments.stages.settings import FollowerSettings, LFSettings
from mbn.host import put
from mbn.networks.programmable import Connection
from mbn.notation import connection_name, connection_names

__all__ = [
    "TURNING_CANDIDATES",
    "LFSearchResult",
    "LFSearchSettings",
    "LFSearchStage",
    "best_triple",
    "rung_ends",
    "search_checkpoint",
    "search_triples",
]

#: The connections into the turning neuron (neuron 2 in the paper's 1-based notation), 0-based.
TURNING_CANDIDATES = ("W[1,0]", "W[1,1]", "W[1,2]", "WE[1,0]", "WE[1,1]", "WE[1,2]")


@dataclass(frozen=True)
class LFSearchSettings(Settings):
    """The search for the 3 connections of RF that LF re-evolves."""

    section = "lf_search"
    # runs recorded before ``halvings`` existed evolved every triple the whole way
    recorded_before: ClassVar[dict[str, Any]] = {"halvings": 0}
    candidates: tuple[str, ...] = setting(
        TURNING_CANDIDATES,
        doc="connections tried, in the code's 0-based form ('W[i,j]', 'WE[i,k]'; 'W[1,2]' is "
        "the paper's W_23); every triple is evolved",
        source="docs/reproduce.md (the connections into the turning neuron)",
    )
    generations: int = setting(
        100, doc="DE generations of the triples that go the whole way", low=0, high=100_000
    )
    halvings: int = setting(
        2,
        doc="successive halving: the triples are evolved in halvings + 1 rungs, ending at "
        "generations / 2^halvings, ..., / 2, generations; after each rung but the last only "
        "the better half (by best fitness then) goes on (0: every triple the whole way)",
        low=0,
        high=6,
        source="docs/speed.md (half the search's robot-steps)",
    )
    variants: int = setting(2, doc="starts per crossroad while searching", low=1, high=100)

    def __post_init__(self) -> None:
        super().__post_init__()
        # connections RF has (3 neurons, 3 inputs), none twice: refused here, not after RF
        follower_connections(self.candidates, "lf_search.candidates")
        if len(self.candidates) < 3:
            raise MbnInputError("lf_search.candidates: need at least 3 connections")


def search_checkpoint(index: int) -> str:
    """The checkpoint name of triple ``index`` (LF starts from the chosen one's population)."""
    return f"lf_search_{index:02d}"


def search_triples(
    ctx: StageContext, rf: Any, key: jax.Array, checkpoint: Callable[[int], str]
) -> list[dict[str, Any]]:
    """Every triple of ``[lf_search] candidates`` of ``rf`` evolved briefly for the left rule
    (triple ``t`` from ``fold_in(key, t)``, checkpoint ``checkpoint(t)``), the triples' DE runs
    side by side (:meth:`StageContext.evolve_group`: one batch of every triple's genomes per
    generation) in rungs of successive halving (``[lf_search] halvings``: after each rung but
    the last, only the better half goes on), each final population scored again with perturbed
    copies on the crossroads entered round a corner too: a row per triple with the generations
    it was evolved, its best plain and best robust genome and fitness."""
    s: LFSearchSettings = ctx.section(LFSearchSettings)
    followers = ctx.section(FollowerSettings)
    approaches = ctx.section(LFSettings).approaches
    cands = [Connection.parse(c) for c in s.candidates]
    triples = list(itertools.combinations(cands, 3))
    # on maze episodes the search runs fewer starts of each maze, as on the crossroads it runs
    # s.variants (2) starts of each where RF and LF run 4
    maze = maze_episodes(ctx)
    starts = maze.search_starts if maze is not None else None
    noise = stage_perturbations(ctx, 3)
    config = de_config(ctx, 3, followers.weight_bound)
    runs = [DERun(checkpoint(t), config, jax.random.fold_in(key, t)) for t in range(len(triples))]
    alive = list(range(len(triples)))
    results: dict[int, Any] = {}
    ends = rung_ends(s.generations, s.halvings)
    for rung, end in enumerate(ends):
        if rung:
            # the better half of the last rung's triples goes on, ranked by their best fitness
            # at its end (from their histories: the same choice after a resume)
            before = ends[rung - 1]
            rank = sorted(alive, key=lambda t: (-results[t].data["history"]["best"][before], t))
            alive = sorted(rank[: max(1, math.ceil(len(alive) / 2))])
        group = [triples[t] for t in alive]
        done = ctx.evolve_group(
            [runs[t] for t in alive],
            training_fitness(
                ctx,
                "left",
                s.variants,
                lambda t, g=group: connection_group_fitness(rf, t, g),
                starts=starts,
            ),
            end,
            f"LF search: {len(alive)} triples side by side"
            + (f" (rung {rung + 1}/{len(ends)})" if len(ends) > 1 else ""),
        )
        results.update(zip(alive, done, strict=True))
    # The final populations scored with perturbed copies too, on the crossroads entered round a
    # corner as in a maze: an LF that keeps its behaviour when its weights move is one the
    # interpreter can emulate. One batch of every triple's, in parts as DE's.
    final_task = training_task(
        ctx, "left", s.variants, approaches, draw=SCORING_DRAW, starts=starts
    )
    choose = connection_group_fitness(rf, final_task, triples)
    final = join_rows(tuple(results[t].state.population for t in range(len(triples))))
    owner = put(np.repeat(np.arange(len(triples)), config.popsize))
    robust_all = np.asarray(split_fitness(robust_fitness(choose, noise), ctx.workers)(final, owner))
    rows = []
    for t, trip in enumerate(triples):
        de = results[t]
        robust = robust_all[t * config.popsize : (t + 1) * config.popsize]
        i = int(np.argmax(robust))
        rows.append(
            {
                "connections": [str(c) for c in trip],
                "generations": int(de.state.generation),
                "best_fitness": de.data["best_fitness"],
                "best_genome": de.data["best_genome"],
                "robust_fitness": float(robust[i]),
                "robust_genome": np.asarray(de.state.population[i], dtype=float).tolist(),
            }
        )
    return rows


def rung_ends(generations: int, halvings: int) -> list[int]:
    """The generations at which the rungs of a successive halving end: ``generations / 2^h``,
    ..., ``generations / 2``, ``generations`` (rounded; repeated ends merged)."""
    ends = [round(generations / 2**h) for h in range(halvings, -1, -1)]
    return sorted(set(ends))


def best_triple(rows: list[dict[str, Any]]) -> int:
    """The row with the best robust fitness (the first of equals)."""
    return max(range(len(rows)), key=lambda i: (rows[i]["robust_fitness"], -i))


@dataclass(frozen=True, kw_only=True)
class LFSearchResult(Record):
    """What the ``lf_search`` stage records (``stages/lf_search.json``): every triple's row
    (:func:`search_triples`: its connections, DE fitness and genome, robust fitness and
    genome), the chosen triple (by index, connections and the paper's notation), the search's
    budget, the robust fitness's perturbations and the approaches it was chosen from."""

    triples: list[dict[str, Any]]
    chosen: list[str]
    chosen_index: int
    chosen_paper_notation: list[str]
    generations: int
    episodes: int
    noise: Perturbation
    choice_approaches: list[str]


class LFSearchStage(Stage[LFSearchResult]):
    name = "lf_search"
    key_id = KEYS["lf_search"]
    needs = ("rf",)
    settings = LFSearchSettings
    result = LFSearchResult

    def run(self, ctx: StageContext) -> LFSearchResult:
        s: LFSearchSettings = ctx.settings
        followers = ctx.section(FollowerSettings)
        rows = search_triples(ctx, read_network(ctx, "rf"), ctx.key, search_checkpoint)
        best = best_triple(rows)
        return LFSearchResult(
            triples=rows,
            chosen=rows[best]["connections"],
            chosen_index=best,
            chosen_paper_notation=[connection_name(c) for c in rows[best]["connections"]],
            generations=s.generations,
            episodes=s.variants * 7,
            noise=Perturbation(
                copies=followers.perturbation_copies, sigma=followers.perturbation_sigma
            ),
            choice_approaches=list(ctx.section(LFSettings).approaches),
        )

    def summary(self, data: LFSearchResult) -> str:
        return f"chose {connection_names(data.chosen)}"
