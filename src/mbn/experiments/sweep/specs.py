"""What a sweep knows of an experiment: the :class:`SweepSpec` each experiment gives for its runs
(its per-run targets, the tests its report tabulates and plots, where its stages record their DE
curves; ``reproduce/sweep.py`` and its like beside each experiment), the helpers they share, and
:func:`plain_spec` for an experiment that names none (every test its runs recorded, no per-run
target). :func:`sweep_spec` finds an experiment's view through the registry
(:mod:`mbn.experiments.registry`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mbn.errors import MbnInputError
from mbn.experiments.sweep.targets import (
    Target,
)

if TYPE_CHECKING:
    from mbn.experiments.pipeline.document import Section
    from mbn.experiments.pipeline.experiment import Experiment
    from mbn.experiments.pipeline.rundir import RunDir
    from mbn.experiments.registry import Registration

__all__ = [
    "CONTROLLER_DE_STAGES",
    "DEFAULT_EXPERIMENT",
    "FOLLOWERS",
    "SweepSpec",
    "by_trials",
    "controller_curve",
    "loader",
    "plain_spec",
    "stage_history",
    "sweep_spec",
    "with_recorded_tests",
]

#: The experiment a sweep runs unless told otherwise (and a ``sweep.json`` that names none).
DEFAULT_EXPERIMENT = "reproduce"


@dataclass(frozen=True)
class SweepSpec:
    """One experiment as a sweep runs and reports it.

    Attributes:
        name: the experiment's name (``--experiment``).
        title: the report's title.
        command: the command one seed's run is (``mbn reproduce``), for the report's text.
        targets: the per-run targets ("a seed meets every target").
        tests: the tests of ``results.json`` the report tabulates, in order.
        groups: the box plot's groups of tests (title, tests).
        targets_text: the report's sentence on what the targets are.
        de_stages: the stages whose DE best-fitness curves are drawn, with their titles.
        curve: reads one stage's curve from a seed folder (``None`` where it has none).
        load: the experiment (imported when a run needs it).
        generalization: the generalization targets (a seed "meets every generalization
            target"), counted apart from ``targets``: runs made before the ``generalization``
            stage have no record of them.
        analysis: statistics over the finished runs beyond the per-test ones, ``(folder,
            {seed: results.json}) -> (statistics, report sections, figures)`` (``None``: none).
        every_recorded_test: ``tests`` is every test the finished runs recorded, in the order
            of the first run that has each (:func:`with_recorded_tests`), not a fixed list.
    """

    name: str
    title: str
    command: str
    targets: tuple[Target, ...]
    tests: tuple[str, ...]
    groups: tuple[tuple[str, tuple[str, ...]], ...]
    targets_text: str
    de_stages: Mapping[str, str]
    curve: Callable[[RunDir, str], list[float] | None]
    load: Callable[[], Experiment]
    generalization: tuple[Target, ...] = ()
    analysis: (
        Callable[
            [Path, Mapping[int, Mapping[str, Any]]],
            tuple[dict[str, Any], list[Section], list[tuple[str, str]]],
        ]
        | None
    ) = None
    every_recorded_test: bool = False


def stage_history(rundir: RunDir, stage: str) -> list[float] | None:
    """The best fitness per generation a stage recorded (``history.best`` of its data)."""
    if not rundir.stage_done(stage):
        return None
    h = rundir.read_stage(stage).get("history")
    if isinstance(h, dict) and h.get("best"):
        return [float(x) for x in h["best"]]
    return None


def controller_curve(rundir: RunDir, stage: str) -> list[float] | None:
    """As :func:`stage_history`; for the LF search, the chosen triple's checkpoint's history."""
    if stage != "lf_search":
        return stage_history(rundir, stage)
    from mbn.experiments.stages.lf_search import LFSearchStage, search_checkpoint

    if not rundir.stage_done(LFSearchStage.name):
        return None
    try:
        index = rundir.read_result(LFSearchStage).chosen_index
        if not rundir.checkpoint_file(search_checkpoint(index)).exists():
            return None
        cp = rundir.load_checkpoint(search_checkpoint(index))
    except MbnInputError:
        return None
    return [b for b, _ in cp.history]


def loader(name: str) -> Callable[[], Experiment]:
    """How a spec loads its experiment: the registry's entry for ``name``."""

    def load() -> Experiment:
        from mbn.experiments.registry import find

        return find(name).load()

    return load


#: The controllers the tests of the reproduction judge, in the order its report shows them.
FOLLOWERS = ("rf", "lf", "im_rf", "im_lf", "mbn", "published_rf", "published_lf")


def by_trials(first: str, stems: tuple[str, ...]) -> tuple[tuple[str, tuple[str, ...]], ...]:
    """The box plot's panels: ``stems`` from the start marks (titled ``first``), then their
    jittered and their held-out tests."""
    return (
        (first, stems),
        ("Jittered starts", tuple(f"{n}_jitter" for n in stems)),
        ("Held-out maze", tuple(f"{n}_heldout" for n in stems)),
    )


#: The DE stages of the reproduction (and of the experiments that run its stages first).
CONTROLLER_DE_STAGES = {
    "rf": "RF (12 genes)",
    "lf_search": "LF search (the chosen triple)",
    "lf": "LF (3 genes)",
    "pm": "PM (program module)",
}


def plain_spec(registration: Registration) -> SweepSpec:
    """The sweep's view of an experiment that names none: every test its runs recorded (a
    Wilson interval and the spread over the seeds each), no per-run target, no DE curve."""
    return SweepSpec(
        name=registration.name,
        title=f"mbn sweep: {registration.name} over seeds",
        command=registration.run_command,
        targets=(),
        tests=(),
        groups=(),
        targets_text="No test has a per-run target: the experiment names none (its "
        "registration gives no sweep view); every test its runs recorded is tabulated.",
        de_stages={},
        curve=stage_history,
        load=registration.load,
        every_recorded_test=True,
    )


def with_recorded_tests(spec: SweepSpec, runs: Mapping[int, Mapping[str, Any] | None]) -> SweepSpec:
    """``spec`` with its tests made concrete: for a spec of every recorded test, the tests of
    the finished runs' ``results.json`` (in the order of the first run that has each, one
    group); any other spec as it is."""
    if not spec.every_recorded_test:
        return spec
    names: dict[str, None] = {}
    for results in runs.values():
        for name in (results or {}).get("tests", {}) or {}:
            names.setdefault(name, None)
    tests = tuple(names)
    return dataclasses.replace(spec, tests=tests, groups=(("Tests", tests),) if tests else ())


def sweep_spec(name: str | None) -> SweepSpec:
    """The sweep's view of experiment ``name`` (a registered name or a reference; ``None``:
    :data:`DEFAULT_EXPERIMENT`)."""
    from mbn.experiments.registry import find, load_object

    registration = find(DEFAULT_EXPERIMENT if name is None else name)
    if registration.sweep is None:
        return plain_spec(registration)
    value = load_object(registration.sweep)
    if not isinstance(value, SweepSpec):
        raise MbnInputError(
            f"experiment {registration.name}: its sweep {registration.sweep} is a "
            f"{type(value).__name__}, not a SweepSpec (mbn.experiments.sweep.specs.SweepSpec)"
        )
    return value
