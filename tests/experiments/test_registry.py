"""The one registry of experiments (``mbn.experiments.registry``): ``mbn run``, ``mbn sweep`` and
their ``--help`` read it; an experiment kept outside ``mbn`` (a file, a module, an installed
package's entry point) runs with a run's checkpoints, resume, determinism and a sweep's report."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mbn.cli.main import main
from mbn.errors import MbnInputError
from mbn.experiments import registry
from mbn.experiments.pipeline.experiment import Experiment
from mbn.experiments.registry import find, load_object, register, registered

#: An experiment as a lab writes it in a file of its own (docs/architecture.md, "Your own
#: experiment"): one DE stage, checkpointed every generation, and a test of its best genome.
EXAMPLE = Path(__file__).parents[2] / "docs" / "examples" / "sphere_demo.py"


@pytest.fixture
def outside(tmp_path: Path) -> Path:
    path = tmp_path / "lab" / "sphere_demo.py"
    path.parent.mkdir()
    path.write_text(EXAMPLE.read_text())  # outside src/mbn and outside the checkout
    return path


def test_the_registry_lists_mbns_experiments_each_loading_the_experiment_of_its_name():
    names = tuple(registered())
    # the reproduction first; a newly registered experiment joins without editing this test
    assert names[0] == "reproduce"
    assert {"new-behaviours", "noise", "ablations", "programs-vs-dynamics"} <= set(names)
    for name, registration in registered().items():
        experiment = registration.load()
        assert isinstance(experiment, Experiment) and experiment.name == name
        assert registration.help and find(name) is registration
    assert find("reproduce").run_command == "mbn reproduce"
    assert find("noise").run_command == "mbn run noise"


def test_run_and_sweep_help_name_every_registered_experiment(capsys):
    for command in (["run", "--help"], ["sweep", "--help"]):
        with pytest.raises(SystemExit) as exc:
            main(command)
        assert exc.value.code == 0
        text = " ".join(capsys.readouterr().out.split())
        for name in registered():
            assert name in text, (command, name)
        assert "package.module:ATTRIBUTE" in text


def test_register_refuses_a_bad_name_a_bad_reference_and_a_name_taken():
    with pytest.raises(ValueError, match="lower-case words"):
        register("My Rule", "pkg.mod:X")
    with pytest.raises(ValueError, match=r"not 'package\.module:ATTRIBUTE'"):
        register("my-rule", "pkg.mod")
    with pytest.raises(ValueError, match="registered already"):
        register("reproduce", "pkg.mod:X")


@pytest.mark.parametrize(
    ("name", "says"),
    [
        ("nope", "not a registered experiment (ablations, new-behaviours, noise"),
        ("no_such_module_here:EXPERIMENT", "no module of that name"),
        ("mbn.paper:NO_SUCH_THING", "mbn.paper has no NO_SUCH_THING"),
        ("missing/file.py:EXPERIMENT", "no file missing/file.py"),
    ],
)
def test_an_unknown_experiment_is_one_line_with_exit_2(capsys, tmp_path, name, says):
    assert main(["run", name, "--quick", "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and says in err, err
    assert not (tmp_path / "run").exists()


def test_a_reference_to_something_not_an_experiment_is_refused(outside):
    with pytest.raises(MbnInputError, match="is a type, not an mbn Experiment"):
        find(f"{outside}:SphereSettings").load()


def test_an_experiment_in_a_file_of_its_own_runs_resumes_and_repeats(capsys, outside, tmp_path):
    ref = f"{outside}:EXPERIMENT"
    out = tmp_path / "run"
    assert main(["run", ref, "--quick", "--seed", "4", "--out", str(out), "--quiet"]) == 0
    results = json.loads((out / "results.json").read_text())
    assert results["seed"] == 4 and results["quick"] is True
    assert results["config"]["sphere"]["generations"] == 6
    assert set(results["tests"]) == {"near_zero"}
    assert json.loads((out / "run.json").read_text())["kind"] == "lab.sphere-demo"
    assert (out / "checkpoints" / "sphere.npz").exists()
    # the same seed again, elsewhere: the same stage data, float for float
    again = tmp_path / "again"
    assert main(["run", ref, "--quick", "--seed", "4", "--out", str(again), "--quiet"]) == 0
    assert (again / "stages" / "sphere.json").read_text() == (
        out / "stages" / "sphere.json"
    ).read_text()
    # another run of the same seed takes the finished stage (--reuse)
    third = tmp_path / "third"
    argv = ["run", ref, "--quick", "--seed", "4", "--out", str(third), "--reuse", str(out)]
    assert main(argv) == 0
    assert "stages sphere: taken from" in capsys.readouterr().out
    assert (third / "stages" / "sphere.json").read_text() == (
        out / "stages" / "sphere.json"
    ).read_text()
    # resumed with nothing left to do: the finished stage is kept as it was
    before = (out / "stages" / "sphere.json").read_text()
    assert (
        main(["run", ref, "--quick", "--seed", "4", "--out", str(out), "--resume", "--quiet"]) == 0
    )
    assert (out / "stages" / "sphere.json").read_text() == before
    capsys.readouterr()


def test_a_relative_path_is_recorded_as_the_file_it_names(monkeypatch, outside):
    monkeypatch.chdir(outside.parent.parent)
    found = find("lab/sphere_demo.py:EXPERIMENT")
    assert found.entry_point == found.name == f"{outside.resolve()}:EXPERIMENT"


def test_a_sweep_of_an_outside_experiment_reports_every_test_it_recorded(capsys, outside, tmp_path):
    out = tmp_path / "sweep"
    argv = ["sweep", "--experiment", f"{outside}:EXPERIMENT", "--seeds", "0-1", "--quick"]
    assert main([*argv, "--batched", "--out", str(out), "--quiet"]) == 0
    data = json.loads((out / "sweep.json").read_text())
    assert data["settings"]["experiment"] == f"{outside.resolve()}:EXPERIMENT"
    summary = data["summary"]
    assert summary["finished"] == 2 and summary["targets"] == {}
    tests = summary["tests"]["near_zero"]
    assert len(tests["rates"]) == 2 and tests["pooled"]["trials"] == 6
    assert "near_zero" in (out / "sweep.md").read_text()
    capsys.readouterr()


def test_an_installed_packages_entry_point_registers_its_experiment(monkeypatch, outside):
    from importlib.metadata import EntryPoint

    points = [
        EntryPoint("sphere-demo", f"{outside}:EXPERIMENT", registry.ENTRY_POINT_GROUP),
        EntryPoint("reproduce", "elsewhere:X", registry.ENTRY_POINT_GROUP),  # mbn's name: ignored
    ]
    monkeypatch.setattr(registry, "_PLUGINS", None)
    monkeypatch.setattr(
        "importlib.metadata.entry_points",
        lambda group: [p for p in points if p.group == group],
    )
    found = registered()
    assert list(found)[-1] == "sphere-demo"
    assert found["reproduce"].entry_point == "mbn.experiments.reproduce:REPRODUCE"
    assert found["sphere-demo"].load().kind == "lab.sphere-demo"
    monkeypatch.setattr(registry, "_PLUGINS", None)


def test_load_object_reads_a_module_attribute_path():
    assert load_object("mbn.experiments.registry:find") is find
    assert load_object("mbn.experiments.registry:Registration.load") is registry.Registration.load
