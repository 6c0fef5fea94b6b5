"""Tests of the ``programs`` stage: new rules learned by the fixed interpreter's programs alone."""

from __future__ import annotations

import dataclasses
import json

import jax.numpy as jnp
import numpy as np
import pytest

from mbn.controllers import read_controller_spec
from mbn.errors import MbnInputError
from mbn.experiments.behaviours import NEW_BEHAVIOURS
from mbn.experiments.pipeline.runner import replace_section, run_stage
from mbn.experiments.stages.programs import ProgramsSettings, program_network
from mbn.world.mazes.load import load_maze


@pytest.mark.slow
def test_programs_are_found_for_the_new_rules_with_the_interpreter_unchanged(nb_copy):
    rundir, conns = nb_copy
    before = read_controller_spec(rundir.controller_file("im_full"))
    data = run_stage(
        NEW_BEHAVIOURS, rundir, "programs", seed=3, config=NEW_BEHAVIOURS.config(quick=True)
    )
    assert set(data["rules"]) == {"straight-right", "straight-left"}
    assert data["sha256"] == before.interpreter.digest() and data["sha256_checked"]
    out = read_controller_spec(rundir.controller_file("im_full_programs"))
    assert out.interpreter.digest() == before.interpreter.digest()
    assert set(out.programs) == {"right", "left", "straight-right", "straight-left"}
    base = read_controller_spec(rundir.controller_file("rf")).net
    for rule, found in data["rules"].items():
        program = np.asarray(out.programs[rule])
        assert program.shape == (len(conns),)
        assert np.all((program >= 0) & (program <= 1))
        # the program is a network: decoded, its weights are the recorded ones
        net = program_network(out.interpreter, base, program)
        np.testing.assert_allclose(np.asarray(net.W), found["network"]["W"], atol=1e-6)
        for c in out.interpreter.connections:
            assert float(c.value(net)) == pytest.approx(found["weights"][str(c)], abs=1e-5)
        # validated in the [validation] mazes and the three-tile validation maze, pooled
        settings = NEW_BEHAVIOURS.config(quick=True)
        v = settings["validation"]
        names = (v.maze, *v.extra_mazes, *settings["programs"].validation_mazes)
        assert "tiles3_validation" in names
        marks = sum(len(load_maze(n).starts) for n in names)
        for key in ("validation_im", "validation_network"):
            assert found[key]["trials"] == marks * v.jitter_per_mark
        # every member of the final population validated as its network, the best few through
        # the interpreter too; the one kept is the best of those by the worse of the two
        pv = found["population_validation"]
        assert len(pv["successes"]) == settings["de"].popsize
        checked = pv["checked"]
        assert len(checked) == min(settings["programs"].members, len(pv["successes"]))
        best_alone = sorted(pv["successes"], reverse=True)[: len(checked)]
        assert sorted(c["network"] for c in checked) == sorted(best_alone)
        worst = [min(c["im"], c["network"]) for c in checked]
        kept = next(c for c in checked if c["member"] == found["member"])
        assert min(kept["im"], kept["network"]) == max(worst)
        assert found["validation_network"]["successes"] == kept["network"]


def test_an_interpreter_whose_weights_changed_is_refused(nb_copy):
    rundir, _ = nb_copy
    path = rundir.controller_file("im_full")
    data = json.loads(path.read_text())
    data["interpreter"]["net"]["W"][0][0] += 0.5
    path.write_text(json.dumps(data))
    with pytest.raises(MbnInputError, match=r"sha256 .* weights were changed"):
        run_stage(
            NEW_BEHAVIOURS, rundir, "programs", seed=3, config=NEW_BEHAVIOURS.config(quick=True)
        )


def test_a_test_maze_is_refused_for_validation(nb_copy):
    rundir, _ = nb_copy
    config = NEW_BEHAVIOURS.config(quick=True)
    config = replace_section(
        config, dataclasses.replace(config["programs"], validation_mazes=("tiles3",))
    )
    with pytest.raises(
        MbnInputError,
        match=r"^programs\.validation_mazes\[0\]: 'tiles3' is a test maze \(\[tests3\] maze\)",
    ):
        run_stage(NEW_BEHAVIOURS, rundir, "programs", seed=3, config=config)


def test_rules_are_checked():
    with pytest.raises(MbnInputError, match=r"programs\.rules: unknown rule"):
        ProgramsSettings(rules=("sideways",))
    with pytest.raises(MbnInputError, match="listed twice"):
        ProgramsSettings(rules=("straight-right", "SRL"))
    with pytest.raises(MbnInputError, match="RF's and LF's"):
        ProgramsSettings(rules=("right",))
    with pytest.raises(MbnInputError, match=r"^programs\.rules: no rule: the stage learns"):
        ProgramsSettings(rules=())


@pytest.mark.slow
def test_the_quick_experiment_runs_end_to_end_and_resumes(tmp_path):
    """``mbn run new-behaviours --quick``: every stage, the files ``mbn evaluate`` loads, the
    interpreter's sha256 the same in each, and a second run with --resume changes nothing."""
    import subprocess
    import sys

    out = tmp_path / "nb"
    cmd = [sys.executable, "-m", "mbn", "run", "new-behaviours", "--quick", "--quiet"]
    proc = subprocess.run([*cmd, "--out", str(out), "--seed", "1"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    results = json.loads((out / "results.json").read_text())
    for name in ("im_full_rf_jitter", "im_full_straight_right", "mbn3_jitter", "mbn3_two_tiles"):
        assert results["tests"][name]["trials"] > 0
    # every per-run target of a sweep of this experiment finds its record (mbn sweep
    # --experiment new-behaviours)
    from mbn.experiments.behaviours.sweep import NEW_BEHAVIOURS_SPEC
    from mbn.experiments.sweep.targets import measure

    for target in NEW_BEHAVIOURS_SPEC.targets:
        assert measure(target, results)[1] > 0, target.name
    assert set(NEW_BEHAVIOURS_SPEC.tests) == set(results["tests"])
    digests = set()
    for f in ("im_full", "im_full_programs", "mbn3"):
        spec = read_controller_spec(out / "controllers" / f"{f}.json")
        im = getattr(spec, "interpreter_spec", spec)
        digests.add(im.interpreter.digest())
    assert digests == {results["stages"]["im_full"]["sha256"]}
    mbn3 = read_controller_spec(out / "controllers" / "mbn3.json")
    assert mbn3.tile_rules == ("right", "left", "straight-right")
    before = (out / "results.json").read_bytes()
    again = subprocess.run(
        [*cmd, "--out", str(out), "--seed", "1", "--resume"], capture_output=True, text=True
    )
    assert again.returncode == 0, again.stderr
    assert json.loads((out / "results.json").read_text())["tests"] == json.loads(before)["tests"]
    # an interpreter whose weights changed is refused when the run checks it again: one line,
    # exit 2, nothing written
    path = out / "controllers" / "im_full_programs.json"
    data = json.loads(path.read_text())
    data["interpreter"]["net"]["W"][0][0] += 0.25
    path.write_text(json.dumps(data))
    (out / "stages" / "tests3.json").unlink()
    bad = subprocess.run(
        [*cmd, "--out", str(out), "--seed", "1", "--resume"], capture_output=True, text=True
    )
    assert bad.returncode == 2
    lines = [x for x in bad.stderr.strip().splitlines() if "WARNING" not in x]
    assert len(lines) == 1 and "weights were changed" in lines[0], bad.stderr
    assert not (out / "stages" / "tests3.json").exists()


def test_approaches_are_checked_and_reach_the_programs_crossroads(monkeypatch):
    """``[programs] approaches`` (default the paper's crossroads, entered from the south) is
    checked, and the program search's episodes are the crossroads entered those ways."""
    import jax

    from mbn.experiments.stages import programs as stage
    from mbn.experiments.stages.settings import FollowerSettings
    from mbn.networks.multiplier import load_default
    from mbn.networks.programmable import all_connections, build_interpreter
    from mbn.paper import published_rf

    assert ProgramsSettings().approaches == ("south",)
    assert ProgramsSettings(approaches=("south", "west")).approaches == ("south", "west")
    with pytest.raises(MbnInputError, match=r"programs\.approaches"):
        ProgramsSettings(approaches=("west", "west"))
    with pytest.raises(MbnInputError, match="north"):
        ProgramsSettings(approaches=("north",))

    seen = []

    class Recorded(stage.CrossroadTask):
        def arrays(self):
            seen.append(self.approaches)
            return super().arrays()

    monkeypatch.setattr(stage, "CrossroadTask", Recorded)
    followers = FollowerSettings(episode_seconds=0.5, perturbation_copies=0)
    ctx = type(
        "Ctx",
        (),
        {
            "section": staticmethod(lambda cls: {"followers": followers}[cls.section]),
            "seeds": {"crossroad_jitter": 0},
            "key": jax.random.key(0),
        },
    )()
    rf = published_rf(dtype=np.float32)
    interp = build_interpreter(rf, all_connections(rf, bound=20.0)[:2], load_default())
    values = {}
    for approaches in (("south",), ("south", "west")):
        fitness = stage.program_fitness(ctx, interp, rf, "straight-right", 1, approaches)
        values[approaches] = np.asarray(fitness(np.full((2, 2), 0.5, np.float32)))
        assert seen[-1] == approaches
    # one start per crossroad: 7 episodes from the south, 14 with the west, each at most 1.1
    assert values[("south",)].shape == (2,) and np.all(values[("south",)] <= 7 * 1.1)
    assert not np.array_equal(values[("south",)], values[("south", "west")])


def test_with_maze_episodes_programs_are_scored_on_redrawn_maze_episodes():
    """``[episodes] kind = "maze"``: a program's fitness is the rule's on episodes drawn from
    the train split of the family, drawn again every ``redraw`` generations."""
    import jax

    from mbn.experiments.evolve import Redrawn
    from mbn.experiments.stages import programs as stage
    from mbn.experiments.stages.settings import EpisodeSettings, FollowerSettings
    from mbn.networks.multiplier import load_default
    from mbn.networks.programmable import all_connections, build_interpreter
    from mbn.paper import published_rf

    followers = FollowerSettings(perturbation_copies=0)
    episodes = EpisodeSettings(kind="maze", pool=3, mazes=2, starts=1, seconds=4.0, redraw=5)
    sections = {"followers": followers, "episodes": episodes}
    ctx = type(
        "Ctx",
        (),
        {
            "section": staticmethod(lambda cls: sections[cls.section]),
            "seeds": {"crossroad_jitter": 0},
            "key": jax.random.key(0),
        },
    )()
    rf = published_rf(dtype=np.float32)
    interp = build_interpreter(rf, all_connections(rf, bound=20.0)[:2], load_default())
    fitness = stage.program_fitness(ctx, interp, rf, "straight-right", 1)
    assert isinstance(fitness, Redrawn) and fitness.every == 5
    programs = jnp.asarray(np.full((2, 2), 0.5, np.float32))
    owner = jnp.zeros(2, jnp.int32)
    first = np.asarray(fitness.at(0)(programs, owner))
    again = np.asarray(fitness.at(4)(programs, owner))  # the same draw
    other = np.asarray(fitness.at(5)(programs, owner))  # the next draw: other episodes
    assert first.shape == (2,) and np.all(np.isfinite(first))
    # two episodes, each at most 1.1 (progress 1, no stall, F_M at most 1 times 0.1)
    assert np.all(first <= 2 * 1.1 + 1e-6)
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)


@pytest.mark.slow
def test_the_three_behaviour_pm_drives_the_robot_in_mazes_where_its_mbn_misses(nb_copy):
    """``[mbn3] maze_generations``: where the MBN misses its validation target, the code PM's
    DE goes on from its reward's last population driving the robot in tiles3 mazes; that MBN is
    validated too and the better one written (its codes those of its genome), the interpreter
    the one hash-checked."""
    from mbn.experiments.program_module import PMGenome
    from mbn.experiments.stages.common import validation_figure
    from mbn.experiments.stages.mbn3 import latched_codes

    rundir, _ = nb_copy
    config = NEW_BEHAVIOURS.config(quick=True)
    run_stage(NEW_BEHAVIOURS, rundir, "programs", seed=3, config=config)
    config = replace_section(config, config["mbn3"].replace(maze_generations=2))
    config = replace_section(
        config, config["episodes"].replace(pool=6, mazes=2, starts=2, seconds=20.0)
    )
    config = replace_section(config, config["validation"].replace(target=1.0, attempts=1))
    data = run_stage(NEW_BEHAVIOURS, rundir, "mbn3", seed=3, config=config)
    maze = data.get("maze")
    if maze is None:
        assert data["validation"]["meets_target"]
        pytest.skip("the reward's MBN met even a 100 % target")
    assert (maze["generations"], maze["family"], maze["episodes"]) == (2, "tiles3", 4)
    assert (rundir.root / "checkpoints" / "mbn3_pm_mazes.npz").exists()
    assert data["attempts"][0]["maze_kept"] == maze["kept"]
    if not maze["kept"]:
        assert validation_figure(maze["validation"]) <= validation_figure(data["validation"])
    spec = read_controller_spec(rundir.controller_file("mbn3"))
    genes = maze["best_genome"] if maze["kept"] else data["best_genome"]
    net = PMGenome(programs=3, inputs=3).network(np.asarray(genes))
    np.testing.assert_allclose(np.asarray(spec.program_module.W), np.asarray(net.W), atol=1e-9)
    codes = latched_codes(spec.program_module, 3)
    for rule, code in zip(data["tile_rules"], codes, strict=True):
        assert data["latched_codes"][rule] == pytest.approx(code.tolist(), abs=1e-6)
    assert data["sha256"] == spec.interpreter_spec.interpreter.digest()
