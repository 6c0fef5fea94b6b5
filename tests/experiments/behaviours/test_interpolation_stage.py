"""The ``interpolation`` stage on a quick run's interpreter and programs."""

from __future__ import annotations

import json

import pytest

from mbn.controllers import read_controller_spec
from mbn.errors import MbnInputError
from mbn.experiments.behaviours import NEW_BEHAVIOURS
from mbn.experiments.pipeline.runner import replace_section, run_stage
from mbn.experiments.switch import SWITCH


@pytest.mark.slow
def test_the_sweep_ends_on_each_program_and_tallies_every_trial(nb_copy):
    rundir, _ = nb_copy
    run_stage(NEW_BEHAVIOURS, rundir, "programs", seed=3, config=NEW_BEHAVIOURS.config(quick=True))
    config = SWITCH.config(quick=True)
    config = replace_section(
        config, config["interpolation"].replace(steps=3, mazes=1, pairs=("right:left",))
    )
    data = run_stage(SWITCH, rundir, "interpolation", seed=3, config=config)
    spec = read_controller_spec(rundir.controller_file("im_full_programs"))
    assert data["sha256"] == spec.interpreter.digest()
    pair = data["pairs"]["right:left"]
    assert [p["alpha"] for p in pair["points"]] == [0.0, 0.5, 1.0]
    for p in pair["points"]:
        assert p["trials"] == data["trials_per_program"] > 0
        # every trial passes by the first rule, the second, both or neither
        assert p["as_first"] + p["as_second"] - p["both"] + p["neither"] == p["trials"]
        assert p["first_exits"] + p["second_exits"] <= p["differing"]
        # the equilibria of the decoded network at every probe, the stable ones first
        assert set(p["equilibria"]) >= {"corridor", "LSR"}
        for points in p["equilibria"].values():
            assert points and points[0]["stable"] in (True, False)
            assert all(-1.0 <= e["w"] <= 1.0 and 0.0 <= e["v"] <= 0.5 for e in points)


@pytest.mark.slow
def test_an_interpreter_whose_weights_changed_is_refused_by_the_sweep(nb_copy):
    rundir, _ = nb_copy
    run_stage(NEW_BEHAVIOURS, rundir, "programs", seed=3, config=NEW_BEHAVIOURS.config(quick=True))
    path = rundir.stage_file("im_full")
    data = json.loads(path.read_text())
    data["sha256"] = "0" * 64
    path.write_text(json.dumps(data))
    with pytest.raises(MbnInputError, match="sha256"):
        run_stage(SWITCH, rundir, "interpolation", seed=3, config=SWITCH.config(quick=True))
