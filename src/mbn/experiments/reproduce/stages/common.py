"""What several stages of ``mbn reproduce`` do alike: DE settings, the crossroad task, fixed weight
perturbations, evolving and scoring a follower, and reading the networks earlier stages saved."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from mbn.controllers import CTRNNControllerSpec, read_controller_spec, save_controller
from mbn.errors import MbnInputError
from mbn.evolution.de import DEConfig
from mbn.experiments.crossroads import CrossroadTask, episode_fitness, paper_terms
from mbn.experiments.evolve import (
    Genome,
    crossroad_fitness,
    evaluate_networks,
    perturbations,
    robust_fitness,
)
from mbn.experiments.pipeline import StageContext
from mbn.networks.ctrnn import CTRNN

__all__ = [
    "MADE_BY",
    "PERTURBATION_KEY",
    "de_config",
    "evolve_follower",
    "read_network",
    "score",
    "stage_perturbations",
    "task",
]

MADE_BY = "mbn reproduce"
#: Folded into a stage's key for its fixed weight perturbations (no generation index reaches it).
PERTURBATION_KEY = 10**6


def de_config(ctx: StageContext, dims: int, bound: float, init: float | None = None) -> DEConfig:
    """DE/best/1/bin with the run's ``[de]`` settings, genes in ``[-bound, bound]`` and the first
    generation drawn in ``[-init, init]`` (default: the bound)."""
    de = ctx.section("de")
    init = bound if init is None else init
    return DEConfig(
        num_dims=dims,
        popsize=de.popsize,
        F=de.F,
        CR=de.CR,
        maximize=True,
        lower=-bound,
        upper=bound,
        init_low=-init,
        init_high=init,
    )


def task(
    ctx: StageContext, rule: str, variants: int, approaches: tuple[str, ...] = ("south",)
) -> CrossroadTask:
    """The crossroad task of the followers, jittered by the run's ``crossroad_jitter`` seed."""
    return CrossroadTask(
        rule=rule,
        variants=variants,
        seconds=ctx.section("followers").episode_seconds,
        seed=ctx.seeds["crossroad_jitter"],
        approaches=approaches,
    )


def score(
    ctx: StageContext,
    net: CTRNN,
    rule: str,
    variants: int,
    approaches: tuple[str, ...] = ("south",),
) -> dict[str, Any]:
    """Branch fitness and the paper's F_M, F_R, F_L of a network on the crossroads."""
    t = task(ctx, rule, variants, approaches)
    arrays = t.arrays()
    tau = float(np.asarray(net.tau).reshape(-1)[0])
    stats = evaluate_networks(jnp.asarray(net.W)[None], jnp.asarray(net.WE)[None], tau, arrays, t)
    terms = paper_terms(stats)
    return {
        "branch_fitness": float(jnp.sum(episode_fitness(stats, arrays, t))),
        "episodes": arrays.episodes,
        "paper_F_M": float(jnp.sum(terms["F_M"])),
        "paper_F_R": float(jnp.sum(terms["F_R"])),
        "paper_F_L": float(jnp.sum(terms["F_L"])),
    }


def stage_perturbations(
    ctx: StageContext, size: int, copies: int | None = None, sigma: float | None = None
) -> jax.Array:
    """The stage's fixed weight perturbations (its key folded with :data:`PERTURBATION_KEY`);
    ``copies`` and ``sigma`` default to the followers'."""
    followers = ctx.section("followers")
    key = jax.random.fold_in(ctx.key, PERTURBATION_KEY)
    copies = followers.perturbation_copies if copies is None else copies
    sigma = followers.perturbation_sigma if sigma is None else sigma
    return perturbations(key, copies, size, sigma)


def read_network(ctx: StageContext, name: str) -> CTRNN:
    """The CTRNN of ``controllers/NAME.json``, saved by stage ``name`` (which must be needed)."""
    if name not in ctx.needs:
        raise RuntimeError(f"stage {ctx.name} reads {name}.json but does not need {name}")
    spec = read_controller_spec(ctx.rundir.controller_file(name))
    if not isinstance(spec, CTRNNControllerSpec):
        raise MbnInputError(f"{ctx.rundir.controller_file(name)}: not a CTRNN controller")
    return spec.net


def evolve_follower(
    ctx: StageContext,
    genome: Genome,
    rule: str,
    variants: int,
    generations: int,
    population: np.ndarray | None = None,
    approaches: tuple[str, ...] = ("south",),
    restarts: int = 1,
) -> dict[str, Any]:
    """Evolve ``genome`` for ``rule`` on the crossroads (fitness averaged over the genome and its
    perturbed copies), ``restarts`` times from independent random populations (restart 0 with
    the stage's key, checkpoint ``NAME``; restart r with the key folded with r, checkpoint
    ``NAME_restartR``), keep the restart with the best fitness, score its best (branch fitness
    and the paper's terms) and save it as ``controllers/NAME.json`` (NAME: the stage's)."""
    name = ctx.name
    followers = ctx.section("followers")
    fitness = robust_fitness(
        crossroad_fitness(genome, task(ctx, rule, variants, approaches)),
        stage_perturbations(ctx, genome.size),
    )
    runs = []
    for r in range(restarts):
        de = ctx.evolve(
            name if r == 0 else f"{name}_restart{r}",
            de_config(ctx, genome.size, followers.weight_bound),
            fitness,
            ctx.key if r == 0 else jax.random.fold_in(ctx.key, r),
            generations,
            f"{name.upper()}: DE generations"
            + (f" (restart {r + 1}/{restarts})" if restarts > 1 else ""),
            population,
        )
        runs.append(de.data)
    chosen = max(range(restarts), key=lambda r: (runs[r]["best_fitness"], -r))
    data = dict(runs[chosen])
    if restarts > 1:
        data["restarts"] = [
            {"best_fitness": d["best_fitness"], "history": d["history"]} for d in runs
        ]
        data["chosen_restart"] = chosen
    net = genome.network(jnp.asarray(data["best_genome"]))
    scored = score(ctx, net, rule, variants, approaches)
    connections = [str(c) for c in genome.connections]
    save_controller(
        ctx.rundir.controller_file(name),
        CTRNNControllerSpec(
            net=net,
            behavior=rule,
            metadata={
                "made_by": MADE_BY,
                "stage": name,
                "seed": ctx.seed,
                "evolved": connections,
                **scored,
            },
        ),
    )
    noise = {"copies": followers.perturbation_copies, "sigma": followers.perturbation_sigma}
    return {
        **data,
        "connections": connections,
        "noise": noise,
        "approaches": list(approaches),
        **scored,
    }
