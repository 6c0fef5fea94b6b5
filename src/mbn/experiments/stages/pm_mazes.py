"""A program module's last generations driving the robot: DE of its genes on episodes in mazes
of its tile family's train split (tiles 0 to a few cells before junctions and in the middle of
corridors), started from the population its robot-free reward left (``docs/generalization.md``,
"The program module driving the robot"), where an MBN misses its validation target. Shared by
the ``pm`` stage (``[pm] maze_generations``) and the code program modules of the three-behaviour
MBN and of the MBNs of K behaviours (``[mbn3]``, ``[scaling] maze_generations``)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import numpy as np

from mbn.experiments.evolve import Redrawn
from mbn.experiments.maze_task import MazeTask
from mbn.experiments.pipeline import StageContext
from mbn.experiments.program_module import PMGenome, pm_maze_fitness
from mbn.experiments.stages.common import (
    de_config,
    episode_maze_task,
    tile_family,
    validate,
    validation_figure,
)
from mbn.experiments.stages.settings import EpisodeSettings

__all__ = ["MAZE_PM_KEY", "evolve_in_mazes", "maze_pm_task", "maze_record", "mend_in_mazes"]

#: The maze generations of an attempt draw from ``fold_in(attempt's key, MAZE_PM_KEY)``.
MAZE_PM_KEY = 11


def maze_pm_task(ctx: StageContext, rules: tuple[str, ...]) -> MazeTask:
    """The first draw of a program module's maze episodes: rule ``"tiles"`` (the rule in force
    is the last tile's, ``rules[0]`` before any) in mazes of the family whose tile kinds put
    ``rules`` in force (:func:`~mbn.experiments.stages.common.tile_family`), with the run's
    ``[episodes]`` pool, mazes, starts, seconds and stall weight, seeded by the run's
    ``crossroad_jitter`` seed (the followers' train pool is of another family), under the run's
    noise (drawn as the followers' training episodes draw theirs)."""
    return episode_maze_task(ctx, "tiles", tile_family(rules), initial=rules[0], tile_rules=rules)


def evolve_in_mazes(
    ctx: StageContext,
    name: str,
    template: Any,
    genome: PMGenome,
    rules: tuple[str, ...],
    population: np.ndarray,
    key: jax.Array,
    generations: int,
    bound: float,
    description: str,
) -> Any:
    """DE (checkpoint ``name``) of the program module of the MBN ``template`` driving the robot
    (:func:`~mbn.experiments.program_module.pm_maze_fitness`) on :func:`maze_pm_task`'s
    episodes, drawn again every ``[episodes] redraw`` generations, for ``generations``
    generations from ``population`` (genes in ``[-bound, bound]``); generation ``g`` draws from
    ``fold_in(key, MAZE_PM_KEY)`` folded with ``g``. Returns DE's result."""
    first = maze_pm_task(ctx, rules)
    fitness: Any = Redrawn(
        lambda d: pm_maze_fitness(template, genome, first.redrawn(d)),
        ctx.section(EpisodeSettings).redraw,
    )
    return ctx.evolve(
        name,
        de_config(ctx, genome.size, bound),
        fitness,
        jax.random.fold_in(key, MAZE_PM_KEY),
        generations,
        description,
        population,
    )


def maze_record(run: Any, task: MazeTask, generations: int) -> dict[str, Any]:
    """What a stage records of :func:`evolve_in_mazes`: DE's best genome and fitness (the sum
    over a draw's episodes, at most ``(1 + 0.1) x episodes``), its generations and history, and
    the family and episodes it drove in."""
    return {
        "best_genome": run.data["best_genome"],
        "best_fitness": run.data["best_fitness"],
        "generations": generations,
        "history": run.data["history"],
        "family": task.family,
        "episodes": task.episodes,
    }


def mend_in_mazes(
    ctx: StageContext,
    name: str,
    template: Any,
    check: dict[str, Any],
    genome: PMGenome,
    rules: tuple[str, ...],
    population: np.ndarray,
    key: jax.Array,
    generations: int,
    bound: float,
    description: str,
    build: Callable[[Any], Any],
) -> tuple[dict[str, Any], Any]:
    """For an MBN ``template`` whose validation ``check`` missed its target: its program
    module's generations driving the robot (:func:`evolve_in_mazes`), the MBN of their best
    genome made by ``build(genes)`` (a spec, or a tuple whose first item is the spec) and
    validated. Returns the :func:`maze_record`, with that MBN's ``validation`` and whether it
    was ``kept`` (validated better than ``check``; the caller keeps it then), and ``build``'s
    result."""
    drove = evolve_in_mazes(
        ctx, name, template, genome, rules, population, key, generations, bound, description
    )
    maze = maze_record(drove, maze_pm_task(ctx, rules), generations)
    built = build(drove.data["best_genome"])
    spec = built[0] if isinstance(built, tuple) else built
    maze["validation"] = validate(ctx, spec, "tiles")
    maze["kept"] = validation_figure(maze["validation"]) > validation_figure(check)
    return maze, built
