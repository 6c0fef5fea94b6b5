"""The machinery every experiment of ``mbn`` runs on: a registry of stages, a run folder, a stage
context (keys, settings, checkpointed DE, progress) and a runner that does resume/force, timings
and ``results.json`` (``docs/architecture.md``).

An experiment is a :class:`~mbn.experiments.pipeline.experiment.Experiment`: a kind, a
:class:`~mbn.experiments.pipeline.registry.Registry` of stages and the settings sections they
share. Adding a stage is one module with a :class:`~mbn.experiments.pipeline.registry.Stage` and
one line in its registry; a stage's result is a
:class:`~mbn.experiments.pipeline.results.Record`, read by the stages after it typed.
"""

from mbn.experiments.pipeline.context import DERun, StageContext
from mbn.experiments.pipeline.experiment import Experiment
from mbn.experiments.pipeline.registry import Registry, Stage
from mbn.experiments.pipeline.results import Record, optional
from mbn.experiments.pipeline.runconfig import RunConfig, RunSettings
from mbn.experiments.pipeline.rundir import RunDir
from mbn.experiments.pipeline.runner import run_experiment

__all__ = [
    "DERun",
    "Experiment",
    "Record",
    "Registry",
    "RunConfig",
    "RunDir",
    "RunSettings",
    "Stage",
    "StageContext",
    "optional",
    "run_experiment",
]
