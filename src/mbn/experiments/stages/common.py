"""What several stages of ``mbn reproduce`` do alike: DE settings, the crossroad task, fixed weight
perturbations, evolving and scoring a follower, and reading the networks earlier stages saved."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from mbn.controllers import (
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    read_controller_spec,
    save_controller,
)
from mbn.errors import MbnInputError
from mbn.evolution.de import DEConfig
from mbn.experiments.crossroads import CrossroadTask
from mbn.experiments.evolve import (
    Genome,
    Redrawn,
    Task,
    crossroad_fitness,
    crossroad_scores,
    perturbations,
    robust_fitness,
)
from mbn.experiments.maze_task import MazeTask
from mbn.experiments.pipeline import StageContext
from mbn.experiments.pipeline.results import Record
from mbn.experiments.stages.settings import (
    DESettings,
    EpisodeSettings,
    FollowerSettings,
    InterpreterSettings,
    TestsSettings,
    ValidationSettings,
)
from mbn.networks.ctrnn import CTRNN
from mbn.networks.multiplier import Multiplier
from mbn.networks.programmable import Interpreter, build_interpreter, differing_connections
from mbn.world.sensors import NoiseConfig

__all__ = [
    "MADE_BY",
    "PERTURBATION_KEY",
    "SCORE_KEYS",
    "SCORING_DRAW",
    "de_config",
    "episode_maze_task",
    "evolve_follower",
    "interpreter_of",
    "maze_episodes",
    "noise_key",
    "read_network",
    "restart_rank",
    "rf_lf_programs",
    "run_noise",
    "save_follower",
    "score",
    "stage_perturbations",
    "task",
    "tile_family",
    "training_fitness",
    "training_task",
    "validate",
    "validation_figure",
    "validation_maze_names",
    "validation_mazes",
    "validation_record",
    "validation_verdict",
]

MADE_BY = "mbn reproduce"
#: Folded into a stage's key for its fixed weight perturbations (no generation index reaches it).
PERTURBATION_KEY = 10**6
#: Folded into a stage's key for the noise of its crossroad episodes, of its validation trials
#: and of its tests (``[noise]``; no generation index reaches them).
FITNESS_NOISE_KEY = 10**6 + 1
VALIDATION_NOISE_KEY = 10**6 + 2
TEST_NOISE_KEY = 10**6 + 3


def run_noise(ctx: StageContext) -> NoiseConfig:
    """The noise the run evolves, validates and tests its controllers under (the ``[noise]``
    section; off, as in an experiment without one, by default: ``docs/noise.md``)."""
    try:
        noise = ctx.section(NoiseConfig)
    except KeyError:
        return NoiseConfig()
    assert isinstance(noise, NoiseConfig)
    return noise


def noise_key(ctx: StageContext, fold: int) -> jax.Array | None:
    """The stage's key for one use of :func:`run_noise` (None when it is off)."""
    return jax.random.fold_in(ctx.key, fold) if run_noise(ctx).enabled else None


def de_config(ctx: StageContext, dims: int, bound: float, init: float | None = None) -> DEConfig:
    """DE/best/1/bin with the run's ``[de]`` settings, genes in ``[-bound, bound]`` and the first
    generation drawn in ``[-init, init]`` (default: the bound)."""
    de = ctx.section(DESettings)
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
    """The crossroad task of the followers, jittered by the run's ``crossroad_jitter`` seed,
    under the run's noise (:func:`run_noise`)."""
    return CrossroadTask(
        rule=rule,
        variants=variants,
        seconds=ctx.section(FollowerSettings).episode_seconds,
        seed=ctx.seeds["crossroad_jitter"],
        approaches=approaches,
        noise=run_noise(ctx),
        noise_key=noise_key(ctx, FITNESS_NOISE_KEY),
    )


#: The draw of maze episodes that scores final populations (no generation's draw reaches it).
SCORING_DRAW = 10**6


def training_task(
    ctx: StageContext,
    rule: str,
    variants: int,
    approaches: tuple[str, ...] = ("south",),
    draw: int = 0,
    starts: int | None = None,
) -> Task:
    """The followers' training task (``[episodes]``): the crossroads (:func:`task`), or draw
    ``draw`` of episodes in mazes of a family's train split (a :class:`MazeTask` seeded by the
    run's ``crossroad_jitter`` seed, under the run's noise; ``starts`` start marks of each maze,
    default ``[episodes] starts``)."""
    episodes = ctx.section(EpisodeSettings)
    if episodes.kind == "crossroads":
        return task(ctx, rule, variants, approaches)
    return episode_maze_task(ctx, rule, episodes.family, starts=starts, draw=draw)


def episode_maze_task(
    ctx: StageContext,
    rule: str,
    family: str,
    *,
    starts: int | None = None,
    draw: int = 0,
    **more: Any,
) -> MazeTask:
    """Draw ``draw`` of ``rule``'s episodes in mazes of ``family``'s train split as the run's
    ``[episodes]`` draws them (pool, mazes, ``starts`` marks of each, default its ``starts``,
    seconds, stall weight), seeded by the run's ``crossroad_jitter`` seed, under the run's
    noise; ``more``: other :class:`MazeTask` fields (a tile rule's ``initial``, ``tile_rules``)."""
    episodes = ctx.section(EpisodeSettings)
    return MazeTask(
        rule=rule,
        family=family,
        pool=episodes.pool,
        mazes=episodes.mazes,
        starts=episodes.starts if starts is None else starts,
        seconds=episodes.seconds,
        stall_weight=episodes.stall_weight,
        seed=ctx.seeds["crossroad_jitter"],
        draw=draw,
        noise=run_noise(ctx),
        noise_key=noise_key(ctx, FITNESS_NOISE_KEY),
        **more,
    )


def training_fitness(
    ctx: StageContext,
    rule: str,
    variants: int,
    make: Any,
    approaches: tuple[str, ...] = ("south",),
    starts: int | None = None,
) -> Any:
    """``make(task)`` of the followers' training task: on the crossroads as it is; on maze
    episodes a :class:`~mbn.experiments.evolve.Redrawn` fitness whose episodes are drawn again
    every ``[episodes] redraw`` generations (``starts``: as :func:`training_task`)."""
    first = training_task(ctx, rule, variants, approaches, starts=starts)
    if not isinstance(first, MazeTask):
        return make(first)
    return Redrawn(lambda d: make(first.redrawn(d)), ctx.section(EpisodeSettings).redraw)


def score(
    ctx: StageContext,
    net: CTRNN,
    rule: str,
    variants: int,
    approaches: tuple[str, ...] = ("south",),
) -> dict[str, Any]:
    """Branch fitness and the paper's F_M, F_R, F_L of a network on the crossroads (the keys
    :data:`SCORE_KEYS`)."""
    t = task(ctx, rule, variants, approaches)
    arrays = t.arrays()
    scores = crossroad_scores(net, t, arrays)
    return {
        "branch_fitness": scores["branch_fitness"],
        "episodes": arrays.episodes,
        "paper_F_M": scores["paper_F_M"],
        "paper_F_R": scores["paper_F_R"],
        "paper_F_L": scores["paper_F_L"],
    }


def stage_perturbations(
    ctx: StageContext, size: int, copies: int | None = None, sigma: float | None = None
) -> jax.Array:
    """The stage's fixed weight perturbations (its key folded with :data:`PERTURBATION_KEY`);
    ``copies`` and ``sigma`` default to the followers'."""
    followers = ctx.section(FollowerSettings)
    key = jax.random.fold_in(ctx.key, PERTURBATION_KEY)
    copies = followers.perturbation_copies if copies is None else copies
    sigma = followers.perturbation_sigma if sigma is None else sigma
    return perturbations(key, copies, size, sigma)


def rf_lf_programs(interp: Interpreter, rf: CTRNN, lf: CTRNN) -> dict[str, list[float]]:
    """An interpreter's programs of RF (``"right"``) and LF (``"left"``), as a controller file
    stores them."""
    return {
        "right": np.asarray(interp.program_of(rf), dtype=float).tolist(),
        "left": np.asarray(interp.program_of(lf), dtype=float).tolist(),
    }


def interpreter_of(
    ctx: StageContext, rf: CTRNN, lf: CTRNN, multiplier: Multiplier, metadata: dict[str, Any]
) -> InterpreterControllerSpec:
    """The interpreter of RF with the connections in which RF and LF differ programmable
    (their two values the bounds, paper eq. 2), RF's and LF's programs, run as the
    ``[interpreter]`` settings say: the ``im`` stage's controller, and the one the LF stage
    checks each candidate with."""
    s = ctx.section(InterpreterSettings)
    interp = build_interpreter(
        rf, differing_connections(rf, lf, margin=0.0), multiplier, tau_ratio=s.tau_ratio
    )
    return InterpreterControllerSpec(
        interpreter=interp,
        programs=rf_lf_programs(interp, rf, lf),
        substeps=s.substeps,
        metadata=metadata,
    )


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
    *,
    name: str | None = None,
    key: jax.Array | None = None,
    validated: bool = False,
    save: bool = True,
) -> dict[str, Any]:
    """Evolve ``genome`` for ``rule`` on the crossroads (fitness averaged over the genome and its
    perturbed copies), ``restarts`` times from independent random populations (restart 0 with
    ``key`` (default the stage's), checkpoint ``NAME`` (default the stage's name); restart r
    with the key folded with r, checkpoint ``NAME_restartR``), and keep the restart with the best
    fitness — or, ``validated``, the fittest of those that meet the validation target on the
    validation maze (:func:`validate`; the one with the best success there when none does),
    evolving up to ``attempts - 1`` more restarts until ``restarts`` of them meet it. Its best
    is scored (branch fitness and the paper's terms) and, ``save``, written as
    ``controllers/NAME.json``. The data holds ``network`` (the CTRNN, not JSON: the caller pops
    it)."""
    name = name or ctx.name
    key = ctx.key if key is None else key
    followers = ctx.section(FollowerSettings)
    perturbed = stage_perturbations(ctx, genome.size)
    fitness = training_fitness(
        ctx,
        rule,
        variants,
        lambda t: robust_fitness(crossroad_fitness(genome, t), perturbed),
        approaches,
    )
    extra = ctx.section(ValidationSettings).attempts - 1 if validated else 0
    runs: list[dict[str, Any]] = []
    r = 0
    while r < restarts + extra:
        total = restarts if r < restarts else restarts + extra
        de = ctx.evolve(
            name if r == 0 else f"{name}_restart{r}",
            de_config(ctx, genome.size, followers.weight_bound),
            fitness,
            key if r == 0 else jax.random.fold_in(key, r),
            generations,
            f"{name.upper()}: DE generations"
            + (f" (restart {r + 1}/{total})" if total > 1 else ""),
            population,
        )
        run = dict(de.data)
        if validated:
            net = genome.network(jnp.asarray(run["best_genome"]))
            run["validation"] = validate(ctx, CTRNNControllerSpec(net=net, behavior=rule), rule)
        runs.append(run)
        r += 1
        # validated: go on until ``restarts`` of them meet the target (the LF stage may build
        # on another RF than the one kept), within the budget
        if r >= restarts and (
            not validated or sum(x["validation"]["meets_target"] for x in runs) >= restarts
        ):
            break

    chosen = max(range(len(runs)), key=lambda i: restart_rank(runs[i], i))
    data = {k: v for k, v in runs[chosen].items() if k != "validation"}
    if runs[chosen].get("validation") is not None:
        data["validation"] = runs[chosen]["validation"]
    if len(runs) > 1:
        data["restarts"] = [
            {
                "best_fitness": d["best_fitness"],
                "history": d["history"],
                "best_genome": d["best_genome"],
                **({"validation": d["validation"]} if "validation" in d else {}),
            }
            for d in runs
        ]
        data["chosen_restart"] = chosen
    net = genome.network(jnp.asarray(data["best_genome"]))
    scored = score(ctx, net, rule, variants, approaches)
    connections = [str(c) for c in genome.connections]
    if save:
        save_follower(ctx, name, net, rule, connections, scored)
    noise = {"copies": followers.perturbation_copies, "sigma": followers.perturbation_sigma}
    return {
        **data,
        "connections": connections,
        "noise": noise,
        "approaches": list(approaches),
        **scored,
        "network": net,
    }


def validation_figure(record: Mapping[str, Any]) -> float:
    """A validation record's figure, by which stages rank their candidates: its pooled success
    rate, and on maze episodes (a record with ``mazes``) the worse of that and the share of the
    validation mazes that reach the target each — the test split's two criteria, so that of two
    candidates the one nearer failing either ranks lower (``docs/generalization.md``)."""
    rate = float(record["success_rate"])
    mazes = record.get("mazes")
    if mazes:
        rate = min(rate, float(record["mazes_at_target"]) / float(mazes))
    return rate


def restart_rank(run: dict[str, Any] | Record, index: int) -> tuple[Any, ...]:
    """The key restarts are ranked by (the highest first): those that met the validation target
    by their fitness, before the others by their success there; the first of equals. ``run``:
    its record (:class:`~mbn.experiments.stages.records.Restart`, or the stage's result when
    it kept its only one), or the same as JSON."""
    if isinstance(run, Record):
        run = run.to_json()
    v = run.get("validation")
    head = (v["meets_target"], 0.0 if v["meets_target"] else v["success_rate"]) if v else ()
    return (*head, run["best_fitness"], -index)


#: What :func:`score` gives, which a follower's file records.
SCORE_KEYS = ("branch_fitness", "episodes", "paper_F_M", "paper_F_R", "paper_F_L")


def save_follower(
    ctx: StageContext,
    name: str,
    net: CTRNN,
    rule: str,
    connections: list[str],
    scored: dict[str, Any],
) -> None:
    """Write an evolved follower as ``controllers/NAME.json``."""
    save_controller(
        ctx.rundir.controller_file(name),
        CTRNNControllerSpec(
            net=net,
            behavior=rule,
            metadata={
                "made_by": MADE_BY,
                "stage": ctx.name,
                "seed": ctx.seed,
                "evolved": connections,
                **scored,
            },
        ),
    )


def validate(
    ctx: StageContext,
    spec: Any,
    behavior: str,
    program: str | None = None,
    *,
    extra: tuple[str, ...] = (),
) -> dict[str, Any]:
    """A candidate's success on the ``[validation]`` maze, which no test uses: every start mark
    once from the mark and ``jitter_per_mark - 1`` times jittered (the run's
    ``validation_jitter`` seed), judged as the tests judge (the test's time limits; the MBN from
    its start by its file's initial rule). ``spec``: a controller spec; ``program``: the stored
    program an interpreter runs; ``extra``: more mazes (names or files) after the
    ``[validation]`` ones."""
    return validation_record(ctx, validation_verdict(ctx, spec, behavior, program, extra=extra))


def maze_episodes(ctx: StageContext) -> EpisodeSettings | None:
    """The run's ``[episodes]`` settings when its stages select on maze episodes (``kind =
    "maze"``), else None (the paper's crossroads, or an experiment without the section)."""
    try:
        episodes = ctx.section(EpisodeSettings)
    except KeyError:
        return None
    return episodes if episodes.kind == "maze" else None


def _validation_trial(
    ctx: StageContext,
    behavior: str,
    initial: str,
    mazes: list[Any],
    tile_rules: tuple[str, ...] = ("right", "left"),
) -> Any:
    """The trials of the validation mazes: every mark, ``jitter_per_mark`` starts each (on maze
    episodes ``split_jitter_per_mark``; the run's ``validation_jitter`` seed), the tests' time
    limits (on maze episodes, at least the longest of the mazes' own)."""
    from mbn.experiments.trials import TrialSpec, route_seconds

    t = ctx.section(TestsSettings)
    v = ctx.section(ValidationSettings)
    maze_kind = maze_episodes(ctx) is not None
    spec = TrialSpec(
        behavior=behavior,
        initial=initial,
        repeats=v.split_jitter_per_mark if maze_kind else v.jitter_per_mark,
        seconds=t.mbn_seconds if behavior == "tiles" else t.seconds,
        seed=ctx.seeds["validation_jitter"],
        tile_rules=tile_rules,
    )
    if maze_kind:
        longest = max(route_seconds(m, spec) for m in mazes)
        spec = dataclasses.replace(spec, seconds=max(spec.seconds, longest))
    return spec


def tile_family(tile_rules: tuple[str, ...]) -> str:
    """The maze family whose tile kinds put ``tile_rules`` in force (an MBN's: ``tiles2`` for
    the paper's right and left, ``tiles3`` for the three-behaviour MBN's; for other rules the
    first registered family with those tile rules, :func:`mbn.world.mazes.families.
    register_family`)."""
    from mbn.world.mazes import families
    from mbn.world.rules import parse_rules

    wanted = tuple(parse_rules(tile_rules, "tile rules"))
    for name, fam in families.FAMILIES.items():
        if fam.tile_rules and fam.tile_rules == wanted:
            return name
    known = "; ".join(
        f"{n}: {', '.join(f.tile_rules)}" for n, f in families.FAMILIES.items() if f.tile_rules
    )
    raise MbnInputError(
        f"no maze family has tiles for the rules {', '.join(tile_rules)} (the families: {known}; "
        "register one: mbn.world.mazes.families.register_family)"
    )


def validation_maze_names(
    ctx: StageContext,
    behavior: str = "right",
    extra: tuple[str, ...] = (),
    tile_rules: tuple[str, ...] = ("right", "left"),
) -> list[str]:
    """The names of the validation mazes, which no test uses: on maze episodes the first
    ``split_mazes`` of the validation split of the family (``[episodes] family``; for an MBN,
    ``behavior`` "tiles", the family of its ``tile_rules``: :func:`tile_family`); else ``maze``
    and ``extra_mazes``; then a stage's own ``extra``."""
    from mbn.world.mazes import families

    v = ctx.section(ValidationSettings)
    episodes = maze_episodes(ctx)
    if episodes is None:
        return [v.maze, *v.extra_mazes, *extra]
    family = tile_family(tile_rules) if behavior == "tiles" else episodes.family
    seeds = families.split_seeds("validation", 0, v.split_mazes - 1, family)
    return [*(f"{family}:{s}" for s in seeds), *extra]


def validation_mazes(
    ctx: StageContext,
    extra: tuple[str, ...] = (),
    behavior: str = "right",
    tile_rules: tuple[str, ...] = ("right", "left"),
) -> list[Any]:
    """The validation mazes (:func:`validation_maze_names`), loaded."""
    from mbn.world.mazes.load import load_maze

    return [load_maze(n) for n in validation_maze_names(ctx, behavior, extra, tile_rules)]


def _joined(verdicts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Verdicts of the same trial spec in several mazes as one (trials in maze order; ``maze``:
    each trial's maze, by index)."""
    from mbn.experiments.trials import join_verdicts

    out = join_verdicts(verdicts)
    out["maze"] = np.concatenate(
        [np.full(len(np.asarray(v["success"])), m, np.int32) for m, v in enumerate(verdicts)]
    )
    return out


def validation_verdict(
    ctx: StageContext,
    spec: Any,
    behavior: str,
    program: str | None = None,
    *,
    extra: tuple[str, ...] = (),
) -> dict[str, np.ndarray]:
    """The judge's verdict (per trial: success, exits, ...) of :func:`validate`'s trials, in
    every validation maze (in order; one batched rollout)."""
    from mbn.controllers import make_controller

    loaded = make_controller(
        spec, program, where=f"{ctx.name} candidate", check_stability=False, noise=run_noise(ctx)
    )
    initial = (loaded.initial_rule or "none") if behavior == "tiles" else "right"
    return validation_verdicts(ctx, [loaded], behavior, initial=initial, extra=extra)[0]


def validation_verdicts(
    ctx: StageContext,
    specs: list[Any],
    behavior: str,
    *,
    initial: str = "right",
    extra: tuple[str, ...] = (),
) -> list[dict[str, Any]]:
    """:func:`validation_verdict` of several controllers of one kind (e.g. a population of
    followers; controller specs or loaded controllers), in one batched rollout over every
    validation maze: one compilation, the same trials for each; under the run's noise
    (:func:`run_noise`)."""
    from mbn.controllers import LoadedController, make_controller
    from mbn.experiments.trials import TrialGroup, run_trial_groups

    noise = run_noise(ctx)
    loaded = [
        spec
        if isinstance(spec, LoadedController)
        else make_controller(
            spec, None, where=f"{ctx.name} candidate", check_stability=False, noise=noise
        )
        for spec in specs
    ]
    first = loaded[0]
    tile_rules = tuple(first.tile_rules or ("right", "left"))
    mazes = validation_mazes(ctx, extra, behavior, tile_rules)
    trial = _validation_trial(ctx, behavior, initial, mazes, tile_rules)
    groups = [
        TrialGroup(f"c{i}m{m}", m, trial, c.initial_state)
        for i, c in enumerate(loaded)
        for m in range(len(mazes))
    ]
    verdicts, _, _, _ = run_trial_groups(
        mazes,
        groups,
        first.controller,
        seconds=trial.seconds,
        dt=first.dt,
        sensors=first.sensors,
        camera=first.camera,
        noise=noise,
        key=noise_key(ctx, VALIDATION_NOISE_KEY),
        until_judged=True,
    )
    return [_joined([verdicts[f"c{i}m{m}"] for m in range(len(mazes))]) for i in range(len(loaded))]


def validation_record(ctx: StageContext, verdict: dict[str, np.ndarray]) -> dict[str, Any]:
    """What :func:`validate` records of a verdict: trials, successes, rate, target met. On
    maze episodes also how many validation mazes reach the target each, and the target is met
    when the pooled rate and ``maze_share`` of the mazes reach it."""
    from mbn.experiments.trials import summary

    v = ctx.section(ValidationSettings)
    out = summary(verdict)
    record = {
        "trials": out["trials"],
        "successes": out["successes"],
        "success_rate": out["success_rate"],
        "meets_target": out["success_rate"] >= v.target,
    }
    if maze_episodes(ctx) is not None and "maze" in verdict:
        maze = np.asarray(verdict["maze"])
        success = np.asarray(verdict["success"])
        rates = [float(success[maze == m].mean()) for m in np.unique(maze)]
        at = sum(r >= v.target for r in rates)
        record["mazes"] = len(rates)
        record["mazes_at_target"] = int(at)
        record["meets_target"] = bool(record["meets_target"] and at >= v.maze_share * len(rates))
    return record
