"""A sphere's minimum found by DE: an experiment kept outside mbn, the smallest one that runs.

    mbn run docs/examples/sphere_demo.py:EXPERIMENT --quick --out runs/sphere
    mbn sweep --experiment docs/examples/sphere_demo.py:EXPERIMENT --seeds 0-3 --out runs/spheres

One stage (DE on a sphere in 3 genes, checkpointed every generation, so that ``--resume``
continues it), one test of its best genome in ``results.json``, and a quick preset. The run
folder, its report, resume, ``--reuse`` and the sweep's statistics over seeds come from mbn
(docs/architecture.md, "Your own experiment").
"""

from dataclasses import dataclass

import jax.numpy as jnp

from mbn.config import Settings, setting
from mbn.evolution.de import DEConfig
from mbn.experiments.pipeline.experiment import Experiment
from mbn.experiments.pipeline.registry import Registry, Stage


@dataclass(frozen=True)
class SphereSettings(Settings):
    """The sphere's DE."""

    section = "sphere"
    generations: int = setting(30, doc="DE generations", low=1, high=10000)


class SphereStage(Stage):
    """DE on the sphere; its data: the best genome and its fitness."""

    name = "sphere"
    key_id = 1
    settings = SphereSettings

    def run(self, ctx):
        config = DEConfig(
            num_dims=3, popsize=8, lower=-5.0, upper=5.0, init_low=-5.0, init_high=5.0
        )
        result = ctx.evolve(
            "sphere",
            config,
            lambda x: jnp.sum(x**2, axis=-1),
            ctx.key,
            ctx.settings.generations,
            "sphere",
        )
        return {
            "best": [float(v) for v in result.state.best_genome],
            "fitness": float(result.state.best_fitness),
        }

    def summary(self, data):
        return f"best fitness {data['fitness']:.3g}"


def results(rundir, stages, config):
    """The run's test: how many of the best genome's genes are within 0.5 of the minimum."""
    hits = sum(abs(v) < 0.5 for v in stages["sphere"]["best"])
    return {"tests": {"near_zero": {"trials": 3, "successes": hits, "success_rate": hits / 3}}}


EXPERIMENT = Experiment(
    name="sphere-demo",
    kind="lab.sphere-demo",
    registry=Registry([SphereStage()]),
    quick={"sphere": {"generations": 6}},
    results=results,
)
