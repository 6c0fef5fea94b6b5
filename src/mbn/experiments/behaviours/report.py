"""The report of ``mbn run new-behaviours``, from the run folder alone: the claims table (the
paper's claim, what was measured, whether it holds), every test, the agreement curve, and
pictures — the three-behaviour MBN's paths in the three-tile maze coloured by the rule in force,
and its three codes around the tile switches."""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp
import numpy as np

from mbn.controllers import MBNControllerSpec, read_controller_spec
from mbn.experiments.generalization import generalization_claims
from mbn.experiments.pipeline import RunDir
from mbn.experiments.pipeline.document import Section, write_document
from mbn.experiments.pipeline.results import ClaimRow, RunResults
from mbn.experiments.stages.generalization import generalization_sections
from mbn.experiments.stages.generalization3 import BehavioursGeneralization
from mbn.experiments.stages.im_full import IMFullStage
from mbn.experiments.stages.programs import ProgramsStage
from mbn.experiments.stages.protocol import AGREEMENT_TARGET, ROBUST_TARGET
from mbn.experiments.stages.records import Tally, TrialSummary
from mbn.experiments.stages.tests3 import MARKS_RECORD, MarksRecording, Tests3Stage
from mbn.io import read_json
from mbn.networks.ctrnn import firing_rate
from mbn.notation import connection_name
from mbn.world.mazes.load import load_maze

__all__ = ["claims", "write_report"]

TITLE = "mbn: new behaviours by programs alone"


def _rate(t: TrialSummary) -> str:
    return f"{t.successes}/{t.trials} ({t.success_rate:.1%})"


def claims(stages: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """Paper claim -> measured -> holds, from the stages' data (as written by the run: read
    here into their records)."""
    im = IMFullStage.from_json(stages[IMFullStage.name])
    t3 = Tests3Stage.from_json(stages[Tests3Stage.name])
    found = ProgramsStage.from_json(stages[ProgramsStage.name])
    tests = {**im.tests, **t3.tests}
    out = []
    full_ok = all(
        tests[f"im_full_{x}"].success_rate == 1.0
        and tests[f"im_full_{x}_jitter"].success_rate >= ROBUST_TARGET
        and tests[f"im_full_{x}_heldout"].success_rate >= ROBUST_TARGET
        and im.agreement[f"im_full_{x}_jitter"].rate >= AGREEMENT_TARGET
        for x in ("rf", "lf")
    )
    a = im.agreement
    out.append(
        {
            "claim": "an interpreter in which all the connections are programmable (discussion)",
            "measured": (
                f"{len(im.connections)} programmable, {im.neurons} neurons, tau_m "
                f"{im.multiplier_tau * 1000:.1f} ms, step {im.step * 1000:.2f} ms; RF's "
                f"program {_rate(tests['im_full_rf_jitter'])} jittered, agreement "
                f"{a['im_full_rf_jitter'].rate:.1%}; LF's {_rate(tests['im_full_lf_jitter'])}, "
                f"agreement {a['im_full_lf_jitter'].rate:.1%}"
            ),
            "target": f"every start mark, >= {ROBUST_TARGET:.0%} jittered and held-out, "
            f"agreement >= {AGREEMENT_TARGET:.0%}",
            "pass": bool(full_ok),
        }
    )
    curve = im.curve
    if curve:
        rf = [r.agreement_rf.rate for r in curve]
        lf = [r.agreement_lf.rate for r in curve]
        first, last = len(curve[0].connections), len(curve[-1].connections)
        worst = [min(a, b) for a, b in zip(rf, lf, strict=True)]
        out.append(
            {
                "claim": "the more programmable connections, the likelier the interpreter's "
                "dynamics drift from the network's (discussion)",
                "measured": (
                    f"agreement with RF {rf[0]:.1%} with {first} programmable, {rf[-1]:.1%} with "
                    f"{last}; with LF {lf[0]:.1%}, {lf[-1]:.1%}"
                ),
                "target": "agreement falls as connections are added (by more than a point)",
                "pass": bool(worst[-1] < worst[0] - 0.01),
            }
        )
    for rule in found.rules:
        short = rule.replace("-", "_")
        ok = (
            tests[f"im_full_{short}"].success_rate == 1.0
            and tests[f"im_full_{short}_jitter"].success_rate >= ROBUST_TARGET
            and tests[f"im_full_{short}_heldout"].success_rate >= ROBUST_TARGET
        )
        out.append(
            {
                "claim": f"a new behaviour ({rule}) acquired by a program alone, the interpreter "
                "unchanged (abstract)",
                "measured": (
                    f"marks {_rate(tests[f'im_full_{short}'])}, jittered "
                    f"{_rate(tests[f'im_full_{short}_jitter'])}, held-out "
                    f"{_rate(tests[f'im_full_{short}_heldout'])}; sha256 unchanged; agreement "
                    f"with its network {t3.agreement[f'im_full_{short}_jitter'].rate:.1%}"
                ),
                "target": f"marks all, >= {ROBUST_TARGET:.0%} jittered and held-out",
                "pass": bool(ok),
            }
        )
    ok = all(
        tests[f"{n}"].success_rate == 1.0
        and tests[f"{n}_jitter"].success_rate >= ROBUST_TARGET
        and tests[f"{n}_heldout"].success_rate >= ROBUST_TARGET
        for n in ("mbn3", "mbn3_two_tiles")
    )
    out.append(
        {
            "claim": "the MBN incrementally trained to show new behaviours by letting PM learn "
            "new programs, without modifying IM (abstract)",
            "measured": (
                f"three tile kinds ({', '.join(t3.tile_rules)}): marks {_rate(tests['mbn3'])}, "
                f"jittered {_rate(tests['mbn3_jitter'])}, held-out "
                f"{_rate(tests['mbn3_heldout'])}; the paper's two tile kinds: "
                f"{_rate(tests['mbn3_two_tiles_jitter'])} jittered, "
                f"{_rate(tests['mbn3_two_tiles_heldout'])} held-out"
            ),
            "target": f"marks all, >= {ROBUST_TARGET:.0%} jittered and held-out, on both",
            "pass": bool(ok),
        }
    )
    for row in generalization_claims(stages.get(BehavioursGeneralization.name)):
        out.append(
            {"claim": row.claim, "measured": row.measured, "target": row.target, "pass": row.passed}
        )
    return out


def _pictures(rundir: RunDir, stages: dict[str, dict[str, Any]]) -> list[tuple[str, str]]:
    from mbn.viz.animate import animate_episode
    from mbn.viz.behaviours import code_traces, rule_paths

    t3 = rundir.read_result(Tests3Stage)
    rec = rundir.load_record_as(MARKS_RECORD, MarksRecording)
    maze = load_maze(t3.mazes.test)
    rules = t3.tile_rules
    initial = t3.initial if t3.initial not in (None, "none") else rules[0]
    pose, tile, t = rec.pose, rec.tile, rec.t
    images = []
    file = "figures/mbn3_paths.png"
    rule_paths(
        maze,
        pose,
        tile,
        rules,
        initial,
        f"Three-behaviour MBN in {maze.name}, from each start mark: the path coloured by the "
        f"rule in force ({int(np.sum(rec.success))}/{len(rec.success)} succeed)",
        rundir.root / file,
    )
    images.append((file, "The three-behaviour MBN's paths, coloured by the rule in force"))
    spec = read_controller_spec(rundir.controller_file("mbn3"))
    assert isinstance(spec, MBNControllerSpec)
    pm = spec.program_module
    codes = np.asarray(firing_rate(pm, jnp.asarray(rec.pm_y, pm.W.dtype)))
    b = int(np.argmax((np.diff(tile, axis=1) != 0).sum(1)))  # the mark with most switches
    file = "figures/mbn3_codes.png"
    code_traces(
        t,
        tile[b],
        codes[b],
        rules,
        f"The PM's three codes from start mark {b + 1} (red: the tile in force changes)",
        rundir.root / file,
    )
    images.append((file, "The program module's codes around the tile switches"))
    file = "figures/mbn3.gif"
    animate_episode(
        maze,
        pose[b],
        rundir.root / file,
        ranges=rec.ranges[b],
        sonars=spec.interpreter_spec.sensors.sonars,
        camera=rec.camera[b],
        tile=tile[b],
        stalled=rec.stalled[b],
        t=t,
        fps=15.0,
        max_frames=150,
        dpi=60,
        title=f"Three-behaviour MBN from start mark {b + 1}",
        camera_fov_deg=spec.camera.fov_deg,
        camera_range=spec.camera.range,
    )
    images.append((file, "The three-behaviour MBN switching behaviour at tiles"))
    return images


def write_report(rundir: RunDir) -> None:
    """``report.md``, ``report.html`` and the figures of a finished run."""
    run = RunResults.pick(read_json(rundir.results), str(rundir.results))
    stages = {name: rundir.read_stage(name) for name in run.stages}
    im = IMFullStage.from_json(stages[IMFullStage.name])
    rows = [ClaimRow.from_json(c) for c in claims(stages)]
    tallies = {name: Tally.pick(found, f"test {name}") for name, found in run.tests.items()}
    secs = [
        Section(
            "What this run did",
            [
                f"Seed {run.seed}. The reproduction's RF and LF; a fully programmable "
                "interpreter of RF; new rules learned by DE over that fixed interpreter's "
                "programs alone; a three-behaviour MBN whose program module alone was evolved. "
                "The interpreter's sha256 "
                f"({im.sha256[:16]}…) was checked in every file written. "
                "docs/behaviours.md describes each stage.",
            ],
        ),
        Section(
            "Claims",
            table=(
                ["claim", "measured", "target", "holds"],
                [[c.claim, c.measured, c.judged_by, "yes" if c.passed else "no"] for c in rows],
            ),
            status=[c.passed for c in rows],
        ),
        Section(
            "Tests",
            table=(
                ["test", "passed", "rate"],
                [
                    [name, f"{t.successes}/{t.trials}", f"{t.success_rate:.1%}"]
                    for name, t in tallies.items()
                ],
            ),
        ),
    ]
    curve = im.curve
    if curve:
        secs.append(
            Section(
                "Agreement against the number of programmable connections",
                [
                    "The interpreter's agreement with RF and LF on the jittered test, connections "
                    "made programmable one by one from the paper's set."
                ],
                table=(
                    ["programmable", "added", "agreement RF", "agreement LF"],
                    [
                        [
                            str(len(r.connections)),
                            connection_name(r.connections[-1]),
                            f"{r.agreement_rf.rate:.1%}",
                            f"{r.agreement_lf.rate:.1%}",
                        ]
                        for r in curve
                    ],
                ),
            )
        )
    generalization = stages.get(BehavioursGeneralization.name)
    if generalization:
        secs.extend(generalization_sections(rundir, generalization))
    secs.append(Section("Pictures", images=_pictures(rundir, stages)))
    write_document(rundir.root, "report", TITLE, secs)
