"""Stage ``tests3``: the new behaviours' tests. Each new rule's program through the fully
programmable interpreter on the three-tile test maze (its start marks; jittered starts) and the
held-out one, judged by that rule, beside the network the program decodes to (agreement); the
three-behaviour MBN on both three-tile mazes, and on the paper's two-tile mazes (the
two-behaviour tests, which adding the third behaviour must keep); and, last, the interpreter's
sha256 in every file the run wrote, checked against the one ``im_full`` recorded."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from mbn.config import Locator, Settings, setting
from mbn.controllers import (
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    MBNControllerSpec,
    make_controller,
    read_controller_spec,
)
from mbn.experiments.named import trial_maze
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.pipeline.results import Record
from mbn.experiments.stages.im_full import IMFullStage
from mbn.experiments.stages.keys import KEYS
from mbn.experiments.stages.programs import ProgramsStage, check_digest
from mbn.experiments.stages.protocol import SUFFIXES
from mbn.experiments.stages.records import Agreement, TestMazes, TrialSummary
from mbn.experiments.stages.tests import TestsSettings
from mbn.experiments.trials import TrialSpec, agreement, run_loaded_trials, run_trials, summary
from mbn.networks.ctrnn import CTRNN
from mbn.world.mazes.load import load_maze

__all__ = ["MarksRecording", "Tests3Result", "Tests3Settings", "Tests3Stage", "trial_specs"]


@dataclass(frozen=True)
class Tests3Settings(Settings):
    """The mazes of the new behaviours' tests."""

    section = "tests3"
    maze: str = setting("tiles3", doc="the three-tile test maze", source="docs/mazes.md")
    heldout_maze: str = setting(
        "tiles3_heldout", doc="a three-tile maze no training sees", source="docs/mazes.md"
    )

    def check_names(self, sections: Mapping[str, Settings], where: Locator) -> None:
        # read and runnable, with the tiles of the three-behaviour MBN tested in them
        owner: Any = next((sections[s] for s in ("mbn3", "contest3") if s in sections), None)
        rules = tuple(owner.tile_rules) if owner is not None else None
        for key in ("maze", "heldout_maze"):
            trial_maze(getattr(self, key), where(self.section, key), rules)


def trial_specs(
    behavior: str,
    t: Any,
    ctx: StageContext,
    initial: str = "right",
    tile_rules: tuple[str, ...] = ("right", "left"),
) -> dict[str, TrialSpec]:
    """The three tests (marks, jittered, held-out) of a controller judged by ``behavior``."""
    seconds = t.mbn_seconds if behavior == "tiles" else t.seconds
    base = TrialSpec(behavior=behavior, initial=initial, seconds=seconds, tile_rules=tile_rules)
    return {
        "": base,
        "_jitter": dataclasses.replace(
            base, repeats=t.jitter_per_mark, exact_first=False, seed=ctx.seeds["test_jitter"]
        ),
        "_heldout": dataclasses.replace(
            base, repeats=t.heldout_repeats, seed=ctx.seeds["heldout_jitter"]
        ),
    }


#: The record of the three-behaviour MBN's trials from the start marks (``records/NAME.npz``).
MARKS_RECORD = "mbn3_marks"


class MarksRecording(NamedTuple):
    """The three-behaviour MBN's trials from the start marks, every step recorded
    (``records/mbn3_marks.npz``, one array per field): times, poses, the tile in force, the
    sonar ranges, the camera, the stalled steps, the program module's potentials, and each
    trial's success."""

    t: np.ndarray
    pose: np.ndarray
    tile: np.ndarray
    ranges: np.ndarray
    camera: np.ndarray
    stalled: np.ndarray
    pm_y: np.ndarray
    success: np.ndarray


@dataclass(frozen=True, kw_only=True)
class Tests3Result(Record):
    """What the ``tests3`` stage records (``stages/tests3.json``): the three-behaviour MBN's and
    the new programs' tests and agreements, the interpreter's digest and where it was checked,
    the mazes and their start marks, the MBN's initial rule and tile rules, and the rates."""

    tests: dict[str, TrialSummary]
    agreement: dict[str, Agreement]
    sha256: str
    sha256_unchanged_in: list[str]
    mazes: TestMazes
    marks: dict[str, int]
    initial: str | None
    tile_rules: list[str]
    rates: dict[str, float]


class Tests3Stage(Stage[Tests3Result]):
    name = "tests3"
    key_id = KEYS["tests3"]
    needs = ("im_full", "programs", "mbn3")
    outputs = ("records/mbn3_marks.npz",)
    settings = Tests3Settings

    result = Tests3Result

    def run(self, ctx: StageContext) -> Tests3Result:
        s: Tests3Settings = ctx.settings
        t = ctx.section(TestsSettings)
        digest = ctx.read(IMFullStage).sha256
        new = {"": load_maze(s.maze), "_jitter": load_maze(s.maze)}
        new["_heldout"] = load_maze(s.heldout_maze)
        old = {"": load_maze(t.maze), "_jitter": load_maze(t.maze)}
        old["_heldout"] = load_maze(t.heldout_maze)
        im = read_controller_spec(ctx.rundir.controller_file("im_full_programs"))
        mbn3 = read_controller_spec(ctx.rundir.controller_file("mbn3"))
        assert isinstance(im, InterpreterControllerSpec) and isinstance(mbn3, MBNControllerSpec)
        rules = ctx.read(ProgramsStage).rules
        tests: dict[str, Any] = {}
        agree: dict[str, Any] = {}
        bar = ctx.progress.task("tests3", len(rules) + 2)
        for i, (rule, found) in enumerate(rules.items()):
            short = rule.replace("-", "_")
            net = CTRNN.from_dict(found["network"], where=f"programs.{rule}.network")
            emulated = make_controller(im, rule, where="im_full_programs")
            # the network at the interpreter's step: the same dynamics, the products exact
            plain = make_controller(
                CTRNNControllerSpec(net=net, substeps=im.substeps), None, where=f"{rule} network"
            )
            specs = trial_specs(rule, t, ctx)
            for suffix in SUFFIXES:
                got, _, _ = run_loaded_trials(new[suffix], specs[suffix], emulated)
                ref, _, _ = run_loaded_trials(new[suffix], specs[suffix], plain)
                tests[f"im_full_{short}{suffix}"] = summary(got)
                tests[f"net_{short}{suffix}"] = summary(ref)
                agree[f"im_full_{short}{suffix}"] = agreement(got, ref)
            ctx.progress.update(bar, completed=i + 1, info=rule)
        loaded = make_controller(mbn3, None, where="mbn3")
        initial = loaded.initial_rule or "none"
        for mazes, name in ((new, "mbn3"), (old, "mbn3_two_tiles")):
            specs = trial_specs("tiles", t, ctx, initial, tuple(mbn3.tile_rules))
            for suffix in SUFFIXES:
                if name == "mbn3" and suffix == "":
                    # the start marks, recorded for the report's pictures
                    got, result, _ = run_trials(
                        mazes[suffix],
                        specs[suffix],
                        loaded.controller,
                        loaded.initial_state,
                        dt=loaded.dt,
                        sensors=loaded.sensors,
                        camera=loaded.camera,
                        record_every=1,
                        record_controller=True,
                    )
                    traj = result.trajectory
                    assert traj is not None
                    recording = MarksRecording(
                        t=np.asarray(traj.t),
                        pose=np.asarray(traj.pose),
                        tile=np.asarray(traj.tile),
                        ranges=np.asarray(traj.ranges),
                        camera=np.asarray(traj.camera),
                        stalled=np.asarray(traj.stalled),
                        pm_y=np.asarray(traj.controller.pm_y),
                        success=np.asarray(got["success"]),
                    )
                    ctx.rundir.save_record(MARKS_RECORD, recording._asdict())
                else:
                    got, _, _ = run_loaded_trials(mazes[suffix], specs[suffix], loaded)
                tests[f"{name}{suffix}"] = summary(got)
            ctx.progress.update(bar, completed=len(rules) + (2 if name != "mbn3" else 1))
        # the interpreter is the one im_full built, in every file the run wrote
        checked = []
        for f in ("im_full", "im_full_programs", "mbn3"):
            spec = read_controller_spec(ctx.rundir.controller_file(f))
            if isinstance(spec, MBNControllerSpec):
                spec = spec.interpreter_spec
            assert isinstance(spec, InterpreterControllerSpec)
            interp = spec.interpreter
            check_digest(interp, digest, f"controllers/{f}.json")
            checked.append(f"controllers/{f}.json")
        return Tests3Result.from_json(
            {
                "tests": tests,
                "agreement": agree,
                "sha256": digest,
                "sha256_unchanged_in": checked,
                "mazes": {"test": s.maze, "heldout": s.heldout_maze},
                "marks": {"test": len(new[""].starts), "heldout": len(new["_heldout"].starts)},
                "initial": initial,
                "tile_rules": list(mbn3.tile_rules),
                "rates": {k: float(np.round(v["success_rate"], 4)) for k, v in tests.items()},
            }
        )

    def summary(self, result: Tests3Result) -> str:
        data = result.to_json()
        r = data["rates"]
        keys = [k for k in r if k.endswith("_jitter") and not k.startswith("net_")]
        return "; ".join(f"{k} {r[k]:.1%}" for k in keys)
