"""Stage ``tests``: the paper's protocol (start marks of the test maze, 3 consecutive junctions),
jittered starts and the held-out maze, for RF, LF, the interpreter with each program, the MBN and
the published weights; the interpreter's agreement with the networks it emulates; and the
recordings the report draws (trajectories of every test, one MBN episode with its state)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import jax
import numpy as np

from mbn.controllers import (
    CTRNNControllerSpec,
    LoadedController,
    MBNControllerSpec,
    make_controller,
    read_controller_spec,
)
from mbn.errors import MbnInputError
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.pipeline.results import Record
from mbn.experiments.stages.common import TEST_NOISE_KEY, noise_key, run_noise
from mbn.experiments.stages.keys import KEYS
from mbn.experiments.stages.protocol import (
    SUFFIXES,
    TEST_NAMES,
    TESTED,
    Protocol,
    protocol_block,
    test_specs,
)
from mbn.experiments.stages.records import Agreement, TestMazes, TrialSummary
from mbn.experiments.stages.settings import TestsSettings
from mbn.experiments.trials import (
    TrialGroup,
    TrialSpec,
    run_trial_groups,
    summary,
    verdict_details,
)
from mbn.experiments.trials import agreement as same_exits
from mbn.networks.ctrnn import firing_rate
from mbn.paper import published_lf, published_rf
from mbn.world.mazes.load import load_maze

__all__ = ["TRAJECTORY_FIELDS", "TestsResult", "TestsSettings", "TestsStage"]

#: Fields of the trajectories recorded for the report.
TRAJECTORY_FIELDS = ("t", "pose", "camera", "tile", "stalled", "v", "w")


def _same_settings(a: LoadedController, b: LoadedController, na: str, nb: str) -> None:
    """Controllers run in one batch must share their run settings."""
    sa, sb = a.spec, b.spec
    ia = sa.interpreter_spec if isinstance(sa, MBNControllerSpec) else sa
    ib = sb.interpreter_spec if isinstance(sb, MBNControllerSpec) else sb
    for attr in ("dt", "substeps", "method", "motor", "sensors"):
        if getattr(ia, attr) != getattr(ib, attr):
            raise MbnInputError(f"{na} and {nb} differ in {attr}: they cannot run in one batch")


@dataclass(frozen=True, kw_only=True)
class TestsResult(Record):
    """What the ``tests`` stage records (``stages/tests.json``): every tested controller's
    judged trials by test name (``rf``, ``rf_jitter``, ``rf_heldout``, ...), the interpreter's
    agreements with the networks it emulates, the trials' details (not kept in
    ``results.json``), the test and held-out mazes, the protocol and the recording's start."""

    tests: dict[str, TrialSummary]
    agreement: dict[str, Agreement]
    details: dict[str, Any]
    mazes: TestMazes
    protocol: Protocol
    recording: dict[str, Any]


class TestsStage(Stage[TestsResult]):
    name = "tests"
    key_id = KEYS["tests"]
    outputs = ("records/test_trajectories.npz", "records/mbn_recording.npz")
    needs = ("rf", "lf", "im", "pm")
    settings = TestsSettings
    result = TestsResult

    def run(self, ctx: StageContext) -> TestsResult:
        s: TestsSettings = ctx.settings
        mazes = [load_maze(s.maze), load_maze(s.heldout_maze)]
        ctl = ctx.rundir.controller_file
        im = read_controller_spec(ctl("im"))
        specs = {
            "rf": (read_controller_spec(ctl("rf")), None),
            "lf": (read_controller_spec(ctl("lf")), None),
            "published_rf": (CTRNNControllerSpec(net=published_rf(), behavior="right"), None),
            "published_lf": (CTRNNControllerSpec(net=published_lf(), behavior="left"), None),
            "im_rf": (im, "right"),
            "im_lf": (im, "left"),
            "mbn": (read_controller_spec(ctl("mbn")), None),
        }
        rules = dict(TESTED)
        batches = [
            ("plain networks", ("rf", "lf", "published_rf", "published_lf"), s.seconds),
            ("interpreter", ("im_rf", "im_lf"), s.seconds),
            ("MBN", ("mbn",), s.mbn_seconds),
        ]
        ran: dict[str, dict[str, TrialSpec]] = {}
        verdicts: dict[str, dict[str, np.ndarray]] = {}
        trajectories: dict[str, Any] = {}
        # the run's noise, if any (docs/noise.md): each batch draws from its own key
        noise = run_noise(ctx)
        key = noise_key(ctx, TEST_NOISE_KEY)
        bar = ctx.progress.task("tests", len(batches))
        for b, (what, names, seconds) in enumerate(batches):
            # the published matrices are run as printed, beyond the step's stability limit
            # (docs/paper-values.md); every evolved controller is checked
            loaded = {
                n: make_controller(
                    specs[n][0],
                    specs[n][1],
                    where=n,
                    check_stability=not n.startswith("published"),
                    noise=noise,
                )
                for n in names
            }
            first = loaded[names[0]]
            groups = []
            for n in names:
                ran[n] = test_specs(
                    rules[n],
                    seconds=seconds,
                    jitter_per_mark=s.jitter_per_mark,
                    heldout_repeats=s.heldout_repeats,
                    test_seed=ctx.seeds["test_jitter"],
                    heldout_seed=ctx.seeds["heldout_jitter"],
                    initial=loaded[n].initial_rule,
                )
                groups += [
                    TrialGroup(
                        f"{n}{suffix}",
                        1 if suffix == "_heldout" else 0,
                        ran[n][suffix],
                        loaded[n].initial_state,
                    )
                    for suffix in SUFFIXES
                ]
            for n in names[1:]:
                _same_settings(first, loaded[n], names[0], n)
            ctx.progress.update(bar, completed=b, info=what)
            v, result, slices, _ = run_trial_groups(
                mazes,
                groups,
                first.controller,
                seconds=seconds,
                dt=first.dt,
                sensors=first.sensors,
                camera=first.camera,
                record_every=2,
                noise=noise,
                key=None if key is None else jax.random.fold_in(key, b),
            )
            verdicts.update(v)
            for n in names:
                sl = slices[n]
                trajectories[n] = jax.tree.map(
                    lambda a, sl=sl: np.asarray(a)[sl], result.trajectory
                )
            ctx.progress.update(bar, completed=b + 1, info=what)
        tests = {name: summary(verdicts[name]) for name in TEST_NAMES}
        agreement = {}
        for im_name, net_name in (("im_rf", "rf"), ("im_lf", "lf")):
            for suffix in SUFFIXES:
                agreement[f"{im_name}{suffix}"] = same_exits(
                    verdicts[f"{im_name}{suffix}"], verdicts[f"{net_name}{suffix}"]
                )
        details = {name: verdict_details(verdicts[name]) for name in TEST_NAMES}
        ctx.rundir.save_trajectories("test_trajectories", trajectories, TRAJECTORY_FIELDS)
        start = _record_mbn(ctx, specs["mbn"][0], mazes[0], ran["mbn"][""])
        return TestsResult.from_json(
            {
                "tests": tests,
                "agreement": agreement,
                "details": details,
                "mazes": {"test": s.maze, "heldout": s.heldout_maze},
                "protocol": protocol_block(ran["rf"], ran["mbn"]).to_json(),
                "recording": {"start_mark": start},
            }
        )

    def metrics(self, data: dict[str, Any]) -> dict[str, Any]:
        return {k: data[k] for k in ("agreement", "mazes", "protocol")}

    def summary(self, data: TestsResult) -> str:
        t = data.tests
        return ", ".join(f"{n} {t[n].successes}/{t[n].trials}" for n, _ in TESTED)


#: Firing rates, compiled (one program per network shape instead of eager operations).
_rates = jax.jit(firing_rate)

#: Folded into the tests' noise key for the recorded MBN episode (the batches take 0, 1, 2).
RECORDING_KEY = 100


def _record_mbn(ctx: StageContext, spec: Any, maze: Any, paper: TrialSpec) -> int:
    """Record one MBN episode from the test maze's start marks every step, with the program it
    sends and the interpreter's firing rates (``records/mbn_recording.npz``): the episode with
    most changes of the tile in force, a success first, to show switching. Returns its start
    mark (0-based)."""
    if not isinstance(spec, MBNControllerSpec):
        raise MbnInputError("controllers/mbn.json: not an MBN controller")
    noise, key = run_noise(ctx), noise_key(ctx, TEST_NOISE_KEY)
    loaded = make_controller(spec, None, where="mbn.json", noise=noise)
    group = TrialGroup("mbn", 0, paper, loaded.initial_state)
    verdicts, result, _, _ = run_trial_groups(
        [maze],
        [group],
        loaded.controller,
        seconds=paper.seconds,
        dt=loaded.dt,
        sensors=loaded.sensors,
        camera=loaded.camera,
        record_every=1,
        record_controller=True,
        noise=noise,
        key=None if key is None else jax.random.fold_in(key, RECORDING_KEY),
    )
    traj = result.trajectory
    assert traj is not None
    tile = np.asarray(traj.tile)
    changes = (np.diff(tile, axis=1) != 0).sum(1) + 100 * np.asarray(verdicts["mbn"]["success"])
    b = int(np.argmax(changes))
    pick = lambda tree: jax.tree.map(lambda a: np.asarray(a)[b], tree)  # noqa: E731
    # the networks are shared by the batch and not recorded: they are the file's
    pm_y, im_y = pick(traj.controller.pm_y), pick(traj.controller.im_y)
    pm, im = spec.program_module, spec.interpreter_spec.interpreter.net
    n0 = spec.interpreter_spec.interpreter.num_original
    ctx.rundir.save_record(
        "mbn_recording",
        {
            "t": np.asarray(traj.t),
            "pose": np.asarray(traj.pose)[b],
            "ranges": np.asarray(traj.ranges)[b],
            "camera": np.asarray(traj.camera)[b],
            "tile": np.asarray(traj.tile)[b],
            "stalled": np.asarray(traj.stalled)[b],
            "v": np.asarray(traj.v)[b],
            "w": np.asarray(traj.w)[b],
            "program": np.asarray(_rates(pm, pm_y))[:, list(spec.program_neurons)],
            "rates": np.asarray(_rates(im, im_y))[:, :n0],
            "start_mark": np.asarray(b),
        },
    )
    return b
