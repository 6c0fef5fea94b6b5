"""DE runs advanced side by side (``StageContext.evolve_group``): each run of a group is what
``evolve`` makes of it alone; the batch always holds every run, so a group resumed with its runs
at different generations (a kill between two runs' checkpoints) ends as an uninterrupted one."""

from __future__ import annotations

import shutil
from typing import Any

import jax
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.evolution.de import DEConfig
from mbn.experiments.evolve import Redrawn
from mbn.experiments.pipeline import (
    DERun,
    Experiment,
    Registry,
    Stage,
    StageContext,
    run_experiment,
)

CONFIG = DEConfig(
    num_dims=3, popsize=8, maximize=False, lower=-5.0, upper=5.0, init_low=-5.0, init_high=5.0
)
CENTRES = np.array([[1.0, 0.0, -1.0], [-2.0, 2.0, 0.5], [0.0, 3.0, 3.0]], np.float32)


def _sphere(population, centres):
    """Exact whatever the batch: NumPy, one genome at a time."""
    pop = np.asarray(population, np.float32)
    return np.array([np.sum((g - c) ** 2) for g, c in zip(pop, centres, strict=True)])


def _experiment(
    generations: int, shapes: list[tuple[int, ...]], group: bool = True, every: int | None = None
):
    class Spheres(Stage):
        name = "spheres"
        key_id = 1

        def run(self, ctx: StageContext) -> dict[str, Any]:
            runs = [DERun(f"s{r}", CONFIG, jax.random.fold_in(ctx.key, r)) for r in range(3)]
            if every is not None:  # the centres move with every draw of episodes

                def drawn(draw):
                    def fitness(population, owner):
                        shapes.append((draw, *population.shape))
                        return _sphere(population, CENTRES[np.asarray(owner)] + draw)

                    return fitness

                results = ctx.evolve_group(runs, Redrawn(drawn, every), generations, "spheres")
                return {"runs": [r.data for r in results]}
            if group:

                def fitness(population, owner):
                    shapes.append(tuple(population.shape))
                    return _sphere(population, CENTRES[np.asarray(owner)])

                results = ctx.evolve_group(runs, fitness, generations, "spheres")
            else:
                results = [
                    ctx.evolve(
                        run.name,
                        run.config,
                        lambda pop, r=r: _sphere(pop, np.repeat(CENTRES[r : r + 1], len(pop), 0)),
                        run.key,
                        generations,
                        run.name,
                    )
                    for r, run in enumerate(runs)
                ]
            return {"runs": [r.data for r in results]}

    return Experiment(name="spheres", kind="mbn.spheres", registry=Registry([Spheres()]))


def _run(folder, generations, shapes=None, group=True, every=None, **kw):
    exp = _experiment(generations, [] if shapes is None else shapes, group, every)
    return run_experiment(exp, folder, seed=5, config=exp.config(), log=lambda _: None, **kw)


def test_each_run_of_a_group_is_the_run_evolved_alone(tmp_path):
    shapes: list[tuple[int, ...]] = []
    together = _run(tmp_path / "group", 6, shapes)["stages"]["spheres"]["runs"]
    alone = _run(tmp_path / "alone", 6, group=False)["stages"]["spheres"]["runs"]
    assert together == alone
    assert [r["best_fitness"] for r in together] == pytest.approx([0.0] * 3, abs=3.0)
    # the batch: the group's 3 x 8 genomes cut into the two parts, every generation
    assert shapes == [(12, 3)] * 2 * 7


def test_a_group_resumed_with_its_runs_at_different_generations_ends_as_an_uninterrupted_one(
    tmp_path,
):
    reference = _run(tmp_path / "reference", 6)["stages"]["spheres"]["runs"]
    _run(tmp_path / "at3", 3)
    _run(tmp_path / "at4", 4)
    folder = tmp_path / "run"
    shutil.copytree(tmp_path / "at3", folder)
    # killed after run 0 saved generation 4, before runs 1 and 2 did
    shutil.copy(tmp_path / "at4" / "checkpoints" / "s0.npz", folder / "checkpoints" / "s0.npz")
    (folder / "stages" / "spheres.json").unlink()
    shapes: list[tuple[int, ...]] = []
    resumed = _run(folder, 6, shapes, resume=True)["stages"]["spheres"]["runs"]
    assert resumed == reference
    assert set(shapes) == {(12, 3)} and len(shapes) == 2 * 3  # generations 4, 5 and 6


def test_a_group_of_different_shapes_is_refused(tmp_path):
    class Mixed(Stage):
        name = "mixed"
        key_id = 1

        def run(self, ctx: StageContext) -> dict[str, Any]:
            other = DEConfig(
                num_dims=2, popsize=8, lower=-5.0, upper=5.0, init_low=-5.0, init_high=5.0
            )
            runs = [DERun("a", CONFIG, ctx.key), DERun("b", other, ctx.key)]
            ctx.evolve_group(runs, lambda p, o: np.zeros(len(p)), 2, "mixed")
            return {}

    exp = Experiment(name="mixed", kind="mbn.mixed", registry=Registry([Mixed()]))
    with pytest.raises(MbnInputError, match="one population shape"):
        run_experiment(exp, tmp_path / "m", seed=0, config=exp.config(), log=lambda _: None)


def test_episodes_redrawn_every_n_generations_judge_the_population_again_first(tmp_path):
    """Every 2 generations the fitness changes (the spheres' centres move by the draw): the
    populations are judged on the new draw before its first trials, so each run's best is its
    value on the last draw; a group resumed in the middle of a draw ends as an uninterrupted
    one."""
    shapes: list[tuple[int, ...]] = []
    runs = _run(tmp_path / "redrawn", 6, shapes, every=2)["stages"]["spheres"]["runs"]
    # draws: generations 0-1 draw 0, 2-3 draw 1, 4-5 draw 2, 6 draw 3; a redraw at 2, 4 and 6
    # judges the population again (two parts each), before the generation's trials
    draws = [s[0] for s in shapes[::2]]
    assert draws == [0, 0, 1, 1, 1, 2, 2, 2, 3, 3]
    for r, run in enumerate(runs):
        genome = np.asarray(run["best_genome"], np.float32)
        assert run["best_fitness"] == pytest.approx(float(np.sum((genome - CENTRES[r] - 3) ** 2)))
    never = _run(tmp_path / "never", 6, every=0)["stages"]["spheres"]["runs"]
    assert never == _run(tmp_path / "group", 6)["stages"]["spheres"]["runs"]
    _run(tmp_path / "at3", 3, every=2)
    folder = tmp_path / "resumed"
    shutil.copytree(tmp_path / "at3", folder)
    (folder / "stages" / "spheres.json").unlink()
    resumed = _run(folder, 6, every=2, resume=True)["stages"]["spheres"]["runs"]
    assert resumed == runs


def test_a_redraw_interval_must_be_a_whole_number_of_generations():
    with pytest.raises(MbnInputError, match="redraw every must be an integer >= 0"):
        Redrawn(lambda d: None, -1)
