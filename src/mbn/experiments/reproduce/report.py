"""The report of ``mbn reproduce``: figures, ``report.md`` and a self-contained ``report.html``,
rendered from the run folder and its ``results.json`` alone (it never simulates: the stages record
what it draws, ``records/``).

The figures go to ``figures/`` (PNG, and a GIF of the MBN); ``report.md`` links them,
``report.html`` embeds them (base64), so it can be mailed or opened anywhere. Both are built from
the same list of sections.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from mbn.controllers import MBNControllerSpec, read_controller_spec
from mbn.errors import MbnInputError
from mbn.experiments.pipeline.document import Section, write_document
from mbn.experiments.pipeline.results import RunResults
from mbn.experiments.pipeline.rundir import RunDir
from mbn.experiments.stages.generalization import (
    ReproduceGeneralization,
    generalization_sections,
)
from mbn.experiments.stages.im import IMStage
from mbn.experiments.stages.lf import LFStage
from mbn.experiments.stages.lf_search import LFSearchStage
from mbn.experiments.stages.multiplier import GRID_RECORD, MultiplierGrid, MultiplierStage
from mbn.experiments.stages.pm import LatchedStart, PMStage
from mbn.experiments.stages.protocol import TESTED
from mbn.experiments.stages.rf import RFResult, RFStage
from mbn.experiments.stages.settings import (
    DESettings,
    EpisodeSettings,
    FollowerSettings,
)
from mbn.experiments.stages.tests import TestsStage
from mbn.io import read_json
from mbn.networks.programmable import differing_connections
from mbn.notation import connection_names
from mbn.paper import published_lf, published_rf
from mbn.viz.multiplier import draw_multiplier_error
from mbn.viz.runs import de_curves, mbn_animation, mbn_traces, test_trajectories
from mbn.world.mazes.load import load_maze

__all__ = ["TITLE", "write_report"]

TITLE = "mbn reproduce: the Multiple Behavior Network, end to end"


Image = tuple[str, str]


@dataclass(frozen=True)
class _Figures:
    """The report's figures, each ``(file, caption)``."""

    multiplier: Image
    de: Image
    trajectories: list[Image]
    traces: Image
    gif: Image


def _figures(rundir: RunDir, results: dict[str, Any]) -> _Figures:
    """Draw every figure into ``figures/``."""
    stages = {name: rundir.read_stage(name) for name in RunResults.pick(results).stages}
    mul = rundir.read_result(MultiplierStage)
    grid = rundir.load_record_as(GRID_RECORD, MultiplierGrid)
    draw_multiplier_error(
        grid.grid,
        grid.output,
        rundir.figure_file("multiplier_error.png"),
        num_neurons=mul.neurons,
    )
    multiplier = (
        "figures/multiplier_error.png",
        "The multiplier's absolute and relative error over [0, 1]^2",
    )
    de_curves(stages, rundir.figure_file("de_curves.png"))
    de = ("figures/de_curves.png", "DE: best and mean fitness per generation")
    tests = rundir.read_result(TestsStage)
    maze = load_maze(tests.mazes.test)
    trajectories = rundir.load_trajectories("test_trajectories")
    drawn: list[Image] = []
    for name, rule in TESTED:
        t = tests.tests[name]
        file = f"figures/trajectories_{name}.png"
        test_trajectories(
            maze,
            trajectories[name],
            tests.details[name],
            f"{name} (rule: {rule}) in {maze.name}: {t.successes}/{t.trials}",
            rundir.root / file,
        )
        drawn.append((file, f"{name}: the paper's protocol, one panel per start mark"))
    spec = read_controller_spec(rundir.controller_file("mbn"))
    if not isinstance(spec, MBNControllerSpec):
        raise MbnInputError(f"{rundir.controller_file('mbn')}: not an MBN controller")
    recording = rundir.load_record("mbn_recording")
    im = spec.interpreter_spec
    mbn_traces(
        recording,
        [str(c) for c in im.interpreter.connections],
        im.programs,
        rundir.figure_file("mbn_traces.png"),
    )
    traces = (
        "figures/mbn_traces.png",
        "Camera, program, interpreter neurons and motor commands around behaviour switches",
    )
    mbn_animation(
        maze,
        recording,
        im.sensors.sonars,
        spec.camera.fov_deg,
        spec.camera.range,
        rundir.figure_file("mbn.gif"),
    )
    gif = ("figures/mbn.gif", "The MBN robot switching behaviour at tiles")
    return _Figures(multiplier, de, drawn, traces, gif)


def _sections(rundir: RunDir, results: dict[str, Any], images: _Figures) -> list[Section]:
    run = RunResults.pick(results, str(rundir.results))
    secs = []
    quick = " This is a **quick** smoke run: tiny budgets, the figures are not the paper's." * bool(
        run.quick
    )
    v = run.versions
    secs.append(
        Section(
            "Run",
            [
                f"Seed {run.seed} (derived seeds: "
                + ", ".join(f"{k} {val}" for k, val in run.seeds.items() if k != "seed")
                + f"). mbn {v.mbn}, JAX {v.jax}, Python {v.python} on {v.platform}."
                + quick,
                "Paper: Montone, Donnarumma & Prevete, *A robotic scenario for programmable "
                "fixed-weight neural networks exhibiting multiple behaviors*, ICANNGA 2011. "
                "Where this run departs from the paper, and why: `docs/reproduce.md`.",
            ],
        )
    )
    claims = run.claims
    secs.append(
        Section(
            "Claims: the paper and this run",
            [f"{sum(bool(c.passed) for c in claims)} of {len(claims)} claims hold."],
            table=(
                ["claim", "paper", "measured", "criterion", "holds"],
                [
                    [c.claim, c.paper or "", c.measured, c.judged_by, _yes(bool(c.passed))]
                    for c in claims
                ],
            ),
            status=[c.passed for c in claims],
        )
    )
    tested = rundir.read_result(TestsStage)
    proto = tested.protocol
    jit = proto.jitter
    mbn_initial = proto.mbn_initial  # runs before the MBN's initial state: none
    mbn_junctions = (
        "whose junctions count from the first tile it drives over"
        if mbn_initial == "none"
        else f"which starts in its {mbn_initial} state: the junctions before its first tile are "
        f"judged by the {mbn_initial} rule"
    )
    rows: list[list[str]] = []
    status: list[bool | None] = []
    for name, rule in TESTED:
        for suffix in ("", "_jitter", "_heldout"):
            t = tested.tests[name + suffix]
            rows.append(
                [
                    name + suffix,
                    rule,
                    f"{t.successes}/{t.trials}",
                    f"{t.success_rate:.1%}",
                    f"{t.correct_junctions}/{t.junctions}",
                    f"{t.mean_stall_fraction:.2%}",
                    str(t.timed_out),
                ]
            )
            status.append(None)
    secs.append(
        Section(
            "Tests",
            [
                f"A trial succeeds when the robot takes the rule's exit at each of its first "
                f"{proto.junctions} junctions and is stalled at most "
                f"{proto.max_stall_fraction:.0%} of the time until it leaves the last one; "
                f"{proto.seconds:g} s per trial ({proto.mbn_seconds:g} s for the MBN, "
                f"{mbn_junctions}); a trial that ends before its last junction with no wrong exit "
                "and no stall failure is counted as timed out (not a success). Paper protocol: "
                "the start "
                f"marks of `{tested.mazes.test}`; `_jitter`: "
                f"{proto.jitter_trials} (lateral +-{jit[0]:g} m, along +-{jit[1]:g} m, heading "
                f"+-{jit[2]:g} deg); "
                f"`_heldout`: maze `{tested.mazes.heldout}`, not used in any "
                f"training: {proto.heldout_trials}.",
                "Interpreter and network take the same branch at every junction in: "
                + "; ".join(
                    f"{k} {a.same_branches}/{a.trials} ({a.rate:.1%})"
                    for k, a in tested.agreement.items()
                )
                + ".",
            ],
            table=(
                ["test", "rule", "successes", "rate", "correct junctions", "stall", "timed out"],
                rows,
            ),
            status=status,
        )
    )
    m = rundir.read_result(MultiplierStage)
    im = rundir.read_result(IMStage)  # the interpreter the run embedded its multipliers in
    tau_ratio, substeps = im.tau_ratio, im.substeps
    grid = m.metrics.grid_points_per_axis
    secs.append(
        Section(
            "Multiplier",
            [
                f"{m.neurons}-neuron multiplier, {m.source}, embedded in the interpreter "
                f"at tau/{1 / tau_ratio:g} (tau_m = {tau_ratio:g} tau), integrated in "
                f"{substeps} steps per robot step. "
                f"Max |error| {m.metrics.max_abs_error_grid:.4f} and mean "
                f"{m.metrics.mean_abs_error_grid:.4f} on a {grid} x {grid} grid of "
                "[0, 1]^2."
            ],
            images=[images.multiplier],
        )
    )
    lf, im = rundir.read_result(LFStage), rundir.read_result(IMStage)
    pm, rf = rundir.read_result(PMStage), rundir.read_result(RFStage)
    search = rundir.read_result(LFSearchStage)
    restarts = len(rf.restarts or []) or 1
    secs.append(
        Section(
            "Evolution",
            [
                *_de_text(rundir, run),
                f"RF: {_count(rf.generations, 'generation')}"
                + (f" in each of {restarts} independent runs" if restarts > 1 else "")
                + f", best fitness {rf.best_fitness:.2f} "
                f"({_fitness_episodes(rundir, run, rf.episodes)}, averaged over the "
                f"genome and {rf.noise.copies} copies perturbed by N(0, "
                f"{rf.noise.sigma}²); "
                + _crossroad_score(rundir, run, rf)
                + f"the paper's terms of "
                f"the best: F_M {rf.paper_F_M:.2f}, F_R {rf.paper_F_R:.2f}, F_L "
                f"{rf.paper_F_L:.2f}).",
                f"LF: the 3 connections re-evolved are {connection_names(lf.connections)} "
                f"(the paper changed {_paper_changed()}), chosen among "
                f"{_count(len(search.triples), 'triple')} evolved "
                f"{_count(search.generations, 'generation')} each; re-evolved for "
                f"{_count(lf.generations, 'generation')}, "
                f"best fitness {lf.best_fitness:.2f}"
                + f"; kept: member {lf.member} of its final population, the best in the "
                f"validation maze ({lf.validation.successes}/"
                f"{lf.validation.trials}), fitness {lf.fitness:.2f}"
                + f" (F_L {lf.paper_F_L:.2f}).",
                f"IM: programmable {connection_names(im.connections)}, "
                f"{im.neurons} neurons; RF program {_vec(im.programs['right'])}, "
                f"LF program {_vec(im.programs['left'])}.",
                (
                    f"PM: {_count(pm.generations, 'generation')} on the program reward, "
                    f"{pm.best_fitness:.2g} (0 at best: minus the mean squared difference "
                    "between the program it sends and the program of the last tile it was shown, "
                    "without the robot; docs/reproduce.md)"
                    if pm.reward == "programs"
                    else f"PM: {_count(pm.generations, 'generation')}, reward "
                    f"{pm.best_fitness:.1f} "
                    f"of at most {pm.max_fitness:.0f} ("
                    + (
                        "the paper's two trials: right-rule score with one-colour tiles x "
                        "left-rule score with two-colour tiles"
                        if pm.reward == "paper"
                        else "the paper's product, over its two trials plus switching, memory "
                        "and rest episodes: docs/experiments.md"
                    )
                    + ")"
                )
                + f", camera range {pm.camera_range:g} m. "
                + _pm_start(pm.initial),
            ],
            images=[images.de],
        )
    )
    secs.append(
        Section(
            "Trajectories",
            [
                "Each test's paper-protocol trials drawn on the maze (tiles: orange one-colour, "
                "blue/magenta two-colour; shaded cells are junctions)."
            ],
            images=images.trajectories,
        )
    )
    secs.append(
        Section(
            "The MBN switching behaviour",
            [
                "One MBN episode recorded every step: what the camera sees, the program the PM "
                "sends, the interpreter's neurons and the motor commands; and the same episode "
                "as an animation."
            ],
            images=[images.traces, images.gif],
        )
    )
    generalization = run.stages.get(ReproduceGeneralization.name)
    if generalization:
        secs.extend(generalization_sections(rundir, generalization))
    timings = rundir.read_timings()
    if timings:
        secs.append(
            Section(
                "Time",
                [
                    "Wall-clock seconds per stage of this run (a resumed run counts only what "
                    "it ran): " + ", ".join(f"{k} {val:g}" for k, val in timings.items()) + "."
                ],
            )
        )
    return secs


def _pm_start(recorded: dict[str, Any] | None) -> str:
    """What the report says of the MBN's initial state (``stages.pm.initial``)."""
    if recorded is None:
        return "The MBN starts with its PM at rest (potentials 0), sending neither program."
    start = LatchedStart.from_json(recorded, "stages/pm.json: initial")
    if start.rule is None or start.program is None:
        return "The PM did not settle after a one-colour tile: the MBN starts with its PM at rest."
    if start.is_rf_program:
        rf = f" (RF's program to within {start.tolerance:g})"
    else:
        rf = (
            f" (RF's program: {_vec(start.rf_program or [])}; largest difference "
            f"{start.max_distance_to_rf_program:.3f})"
        )
    return (
        f"The MBN starts in the state its PM latches after a one-colour tile (settled within "
        f"{start.settled_after_seconds:g} s), sending {_vec(start.program)}{rf}; it "
        f"is judged by the {start.rule} rule before its first tile."
    )


def _de_text(rundir: RunDir, run: RunResults) -> list[str]:
    """The DE settings the run recorded (``[de]``, ``[followers]``, ``[episodes]``), as a
    sentence (none for a run that recorded no ``[de]``)."""
    if not run.recorded(DESettings):
        return []
    where = str(rundir.results)
    de = run.settings(DESettings, where)
    bound = ""
    if run.recorded(FollowerSettings):  # runs before the section: no bound, no episode length
        followers = run.settings(FollowerSettings, where)
        w = followers.weight_bound
        bound = f"; the followers' genes in [-{w:g}, {w:g}]"
        maze = _maze_episodes(rundir, run)
        if maze is not None:
            bound += (
                f", maze episodes of {maze.seconds:g} s ({maze.mazes} mazes x {maze.starts} "
                f"starts a draw from a pool of {maze.pool} {maze.family} train mazes, drawn "
                + (f"again every {maze.redraw} generations" if maze.redraw else "once")
                + ")"
            )
        else:
            bound += f", crossroad episodes of {followers.episode_seconds:g} s"
    return [
        f"DE/best/1/bin for every evolved stage: population {de.popsize}, F {de.F:g}, "
        f"CR {de.CR:g}{bound}."
    ]


def _maze_episodes(rundir: RunDir, run: RunResults) -> EpisodeSettings | None:
    """The run's recorded ``[episodes]`` when its followers evolved on maze episodes, else None
    (the crossroads; also a run recorded before the section existed)."""
    episodes = run.settings(EpisodeSettings, str(rundir.results))
    return episodes if episodes.kind == "maze" else None


def _fitness_episodes(rundir: RunDir, run: RunResults, crossroad_episodes: int) -> str:
    """What RF's best fitness sums over, as the run recorded it."""
    maze = _maze_episodes(rundir, run)
    if maze is None:
        return f"branch fitness over {crossroad_episodes} crossroad episodes"
    return f"junction fitness over the {maze.mazes * maze.starts} maze episodes of a draw"


def _crossroad_score(rundir: RunDir, run: RunResults, rf: RFResult) -> str:
    """For a run evolved on maze episodes, the best's branch fitness on the crossroads (its
    recorded score), where the paper's terms below come from."""
    if _maze_episodes(rundir, run) is None:
        return ""
    return f"on {rf.episodes} crossroad episodes its branch fitness is {rf.branch_fitness:.2f} and "


def _paper_changed() -> str:
    """The connections in which the paper's published RF and LF differ (section 3.1), named."""
    changed = differing_connections(published_rf(), published_lf())
    return connection_names(p.connection for p in changed)


def _count(n: int, noun: str) -> str:
    """``1 triple``, ``20 triples``."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _yes(ok: bool) -> str:
    return "yes" if ok else "no"


def _vec(v: list[float]) -> str:
    return "(" + ", ".join(f"{x:.3g}" for x in v) + ")"


def write_report(rundir: RunDir) -> None:
    """Figures, ``report.md`` and ``report.html`` of a finished run (from its folder alone)."""
    results = read_json(rundir.results)
    images = _figures(rundir, results)
    write_document(rundir.root, "report", TITLE, _sections(rundir, results, images))
