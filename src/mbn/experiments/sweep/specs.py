"""What a sweep knows of each experiment it can run: the experiment, its per-run targets, the
tests its report tabulates and plots, and where its stages record their DE curves.

Each registered experiment (:mod:`mbn.experiments.registry`) names its view here:
``reproduce`` (the default: the paper's experiment, targets
:data:`~mbn.experiments.sweep.targets.TARGETS`), ``new-behaviours`` (``docs/behaviours.md``:
the fully programmable interpreter, the new rules by programs alone and the three-behaviour MBN;
targets :data:`NEW_BEHAVIOURS_TARGETS`, the issue's per-run targets of each section) or
``programs-vs-dynamics`` (``docs/contest.md``: no per-run target; its comparison over runs is
the spec's ``analysis``), ``ablations`` (``docs/ablations.md``: no per-run target; each
ablation's success over the runs) and ``noise`` (``docs/noise.md``: no per-run target; each
channel level by level over the runs, the spec's ``analysis``). An experiment that names none
gets :func:`plain_spec`: every test its runs recorded, no per-run target.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mbn.errors import MbnInputError
from mbn.experiments.reproduce.protocol import SUFFIXES, TEST_NAMES
from mbn.experiments.sweep.targets import (
    GENERALIZATION_TARGETS,
    TARGETS,
    Target,
    generalization_targets,
)

if TYPE_CHECKING:
    from mbn.experiments.pipeline.document import Section
    from mbn.experiments.pipeline.experiment import Experiment
    from mbn.experiments.pipeline.rundir import RunDir
    from mbn.experiments.registry import Registration

__all__ = [
    "ABLATIONS_SPEC",
    "DEFAULT_EXPERIMENT",
    "NEW_BEHAVIOURS_TARGETS",
    "NOISE_SPEC",
    "SweepSpec",
    "experiment_of_kind",
    "plain_spec",
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


def _reproduce_curve(rundir: RunDir, stage: str) -> list[float] | None:
    """As :func:`stage_history`; for the LF search, the chosen triple's checkpoint's history."""
    if stage != "lf_search":
        return stage_history(rundir, stage)
    from mbn.experiments.reproduce.stages.lf_search import search_checkpoint

    if not rundir.stage_done("lf_search"):
        return None
    index = rundir.read_stage("lf_search").get("chosen_index")
    if not isinstance(index, int) or not rundir.checkpoint_file(search_checkpoint(index)).exists():
        return None
    try:
        cp = rundir.load_checkpoint(search_checkpoint(index))
    except MbnInputError:
        return None
    return [b for b, _ in cp.history]


def _registered(name: str) -> Callable[[], Experiment]:
    """How a spec loads its experiment: the registry's entry for ``name``."""

    def load() -> Experiment:
        from mbn.experiments.registry import find

        return find(name).load()

    return load


_FOLLOWERS = ("rf", "lf", "im_rf", "im_lf", "mbn", "published_rf", "published_lf")


def _by_trials(first: str, stems: tuple[str, ...]) -> tuple[tuple[str, tuple[str, ...]], ...]:
    """The box plot's panels: ``stems`` from the start marks (titled ``first``), then their
    jittered and their held-out tests."""
    return (
        (first, stems),
        ("Jittered starts", tuple(f"{n}_jitter" for n in stems)),
        ("Held-out maze", tuple(f"{n}_heldout" for n in stems)),
    )


#: The DE stages of the reproduction (and of the experiments that run its stages first).
REPRODUCE_DE_STAGES = {
    "rf": "RF (12 genes)",
    "lf_search": "LF search (the chosen triple)",
    "lf": "LF (3 genes)",
    "pm": "PM (program module)",
}

REPRODUCE_SPEC = SweepSpec(
    name="reproduce",
    title="mbn sweep: the reproduction over seeds",
    command="mbn reproduce",
    targets=TARGETS,
    generalization=GENERALIZATION_TARGETS,
    tests=tuple(TEST_NAMES),
    groups=_by_trials("Paper protocol", _FOLLOWERS),
    targets_text="The targets (`mbn.experiments.sweep.targets`): the paper protocol in every "
    "trial for RF, LF, the IM with each program and the MBN; at least 95 % on the jittered "
    "starts and on the held-out maze for each; the interpreter takes its network's exits in at "
    "least 98 % of the jittered trials. The published weights have no target.",
    de_stages=REPRODUCE_DE_STAGES,
    curve=_reproduce_curve,
    load=_registered("reproduce"),
)


def _nb_tests(stem: str, what: str) -> tuple[Target, ...]:
    return (
        Target(stem, "tests", stem, Fraction(1), f"{what}: start marks"),
        Target(f"{stem}_jitter", "tests", f"{stem}_jitter", Fraction(95, 100), f"{what}: jittered"),
        Target(
            f"{stem}_heldout", "tests", f"{stem}_heldout", Fraction(95, 100), f"{what}: held-out"
        ),
    )


def _nb_agreement(test: str, where: tuple[str, ...], what: str) -> Target:
    return Target(f"agreement_{test}", "agreement", test, Fraction(98, 100), what, where)


_IM_FULL = ("stages", "im_full", "agreement")
_TESTS3 = ("stages", "tests3", "agreement")

#: The per-run targets of ``new-behaviours`` (issue 19, sections 2 to 4): the fully programmable
#: interpreter with RF's and LF's programs, each new rule by a program alone and its decoded
#: network's agreement with it, and the three-behaviour MBN on three-colour and on two-colour
#: tiles (the two behaviours still there after the third was added).
NEW_BEHAVIOURS_TARGETS: tuple[Target, ...] = (
    *_nb_tests("im_full_rf", "fully programmable IM, RF's program"),
    *_nb_tests("im_full_lf", "fully programmable IM, LF's program"),
    _nb_agreement("im_full_rf_jitter", _IM_FULL, "fully programmable IM takes RF's exits"),
    _nb_agreement("im_full_lf_jitter", _IM_FULL, "fully programmable IM takes LF's exits"),
    *_nb_tests("im_full_straight_right", "straight-right by a program alone"),
    _nb_agreement(
        "im_full_straight_right_jitter", _TESTS3, "the decoded network takes the program's exits"
    ),
    *_nb_tests("im_full_straight_left", "straight-left by a program alone"),
    _nb_agreement(
        "im_full_straight_left_jitter", _TESTS3, "the decoded network takes the program's exits"
    ),
    *_nb_tests("mbn3", "three-behaviour MBN"),
    *_nb_tests("mbn3_two_tiles", "three-behaviour MBN on the two-behaviour test"),
)

#: The tests of a new-behaviours run, from its start marks, in the report's order.
_NB_STEMS = (
    "im_full_rf",
    "im_full_lf",
    "im_full_straight_right",
    "net_straight_right",
    "im_full_straight_left",
    "net_straight_left",
    "mbn3",
    "mbn3_two_tiles",
)
_NB_TESTS = tuple(f"{stem}{suffix}" for stem in _NB_STEMS for suffix in SUFFIXES)

NEW_BEHAVIOURS_SPEC = SweepSpec(
    name="new-behaviours",
    title="mbn sweep: new behaviours by programs alone, over seeds",
    command="mbn run new-behaviours",
    targets=NEW_BEHAVIOURS_TARGETS,
    generalization=generalization_targets(
        (
            ("straight_right", "straight-right by a program alone"),
            ("straight_left", "straight-left by a program alone"),
            ("mbn3", "three-behaviour MBN"),
        )
    ),
    tests=_NB_TESTS,
    groups=_by_trials("Start marks", _NB_STEMS),
    targets_text="The targets (`mbn.experiments.sweep.specs`): every start mark, and at least "
    "95 % of the jittered and the held-out trials, for the fully programmable interpreter with "
    "RF's and with LF's program, for each new rule by a program alone, and for the "
    "three-behaviour MBN on the three-tile maze and on the two-behaviour test; the interpreter "
    "takes RF's and LF's exits, and each new rule's decoded network the program's, in at least "
    "98 % of the jittered trials. The decoded networks (`net_*`) have no target of their own.",
    de_stages={
        "rf": "RF (12 genes)",
        "lf": "LF (3 genes)",
        "mbn3": "PM of the three-behaviour MBN",
    },
    curve=stage_history,
    load=_registered("new-behaviours"),
)


def _contest_analysis(
    out: Path, runs: Mapping[int, Mapping[str, Any]]
) -> tuple[dict[str, Any], list[Section], list[tuple[str, str]]]:
    from mbn.experiments.contest.over_runs import contest_over_runs

    return contest_over_runs(out, runs)


_CONTEST_STEMS = tuple(
    f"{prefix}{who}_{rule}"
    for rule in ("straight_right", "straight_left")
    for prefix, who in (("", "programs"), ("im_", "programs"), ("", "scratch"), ("", "neighbour"))
) + tuple(f"{who}_three_behaviours" for who in ("programs", "monolithic"))

CONTEST_SPEC = SweepSpec(
    name="programs-vs-dynamics",
    title="mbn sweep: learning programs against learning dynamics, over seeds",
    command="mbn run programs-vs-dynamics",
    targets=(),
    tests=tuple(f"{stem}{suffix}" for stem in _CONTEST_STEMS for suffix in SUFFIXES),
    groups=_by_trials("Start marks (each contender's final best)", _CONTEST_STEMS),
    targets_text="No test has a per-run target: the contenders are compared over runs "
    "(below). `im_programs_*` is program search's final program through the interpreter itself; "
    "the others are the networks; `*_three_behaviours`: the three-behaviour task's final "
    "controllers, the MBN (`programs`) and the monolithic CTRNN, judged by the last tile's rule.",
    de_stages={"rf": "RF (12 genes)"},
    curve=stage_history,
    load=_registered("programs-vs-dynamics"),
    analysis=_contest_analysis,
)


#: The ablations of ``mbn run ablations`` (``AblationsSettings.variants``' default, in order;
#: named here so that a sweep's report imports no experiment).
_ABLATIONS = (
    "as_run",
    "wrong_program",
    "frozen_program",
    "exact_products",
    "tau_5",
    "tau_10",
    "tau_20",
    "tau_50",
    "mul3",
)
#: The ablations that change the interpreter (its trials with RF's and LF's programs too).
_ABLATIONS_IM = ("as_run", "exact_products", "tau_5", "tau_10", "tau_20", "tau_50", "mul3")

ABLATIONS_SPEC = SweepSpec(
    name="ablations",
    title="mbn sweep: ablations of the program path, over seeds",
    command="mbn run ablations",
    targets=(),
    tests=(
        *(f"{v}_mbn{x}" for v in _ABLATIONS for x in ("_jitter", "_heldout")),
        *(f"{v}_im_{net}_jitter" for v in _ABLATIONS_IM for net in ("rf", "lf")),
    ),
    groups=(
        ("MBN, jittered starts", tuple(f"{v}_mbn_jitter" for v in _ABLATIONS)),
        ("MBN, held-out maze", tuple(f"{v}_mbn_heldout" for v in _ABLATIONS)),
        ("IM with RF's program, jittered", tuple(f"{v}_im_rf_jitter" for v in _ABLATIONS_IM)),
        ("IM with LF's program, jittered", tuple(f"{v}_im_lf_jitter" for v in _ABLATIONS_IM)),
    ),
    targets_text="No ablation has a per-run target: each is measured over the runs "
    "(`docs/ablations.md`). `V_mbn_*` is the MBN with ablation V on the test maze's jittered "
    "starts and on the held-out maze; `V_im_rf_jitter` and `V_im_lf_jitter` the interpreter "
    "of ablation V with RF's and LF's program, where V changes it.",
    de_stages=REPRODUCE_DE_STAGES,
    curve=_reproduce_curve,
    load=_registered("ablations"),
)


def _noise_analysis(
    out: Path, runs: Mapping[int, Mapping[str, Any]]
) -> tuple[dict[str, Any], list[Section], list[tuple[str, str]]]:
    from mbn.experiments.noise.over_runs import noise_over_runs

    return noise_over_runs(out, runs)


#: The controllers of ``mbn run noise`` (``noise.over_runs.CONTROLLER_NAMES``).
_NOISE_CONTROLLERS = ("rf", "im_rf", "im_lf", "mbn")

NOISE_SPEC = SweepSpec(
    name="noise",
    title="mbn sweep: the controllers under noise, over seeds",
    command="mbn run noise",
    targets=(),
    tests=tuple(
        f"{n}_{p}_{x}"
        for p in ("none", "realistic")
        for n in _NOISE_CONTROLLERS
        for x in ("jitter", "heldout")
    ),
    groups=tuple(
        (title, tuple(f"{n}_{p}_{x}" for n in _NOISE_CONTROLLERS))
        for p, what in (("none", "No noise"), ("realistic", "Realistic noise"))
        for x, title in (("jitter", f"{what}, jittered"), ("heldout", f"{what}, held out"))
    ),
    targets_text="No run has a per-run target here (`docs/noise.md`): `N_none_*` is controller N "
    "without noise, `N_realistic_*` under the realistic noise (its levels as the runs recorded "
    "them: below); the sections below give each channel level by level over the runs.",
    de_stages=REPRODUCE_DE_STAGES,
    curve=_reproduce_curve,
    load=_registered("noise"),
    analysis=_noise_analysis,
)


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


def experiment_of_kind(kind: str) -> Experiment | None:
    """The experiment whose runs record ``kind`` in their ``run.json`` (``mbn.reproduce``), or
    None (how ``--reuse`` finds a source run's stages)."""
    from mbn.experiments.registry import of_kind

    return of_kind(kind)
