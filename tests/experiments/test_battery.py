"""One battery for every registered experiment and every stage it runs (as evosax runs every
registered algorithm through one test), and for an experiment kept outside ``mbn``
(``docs/examples/sphere_demo.py``): a newly registered experiment or stage is tested without a
test of its own.

- **Alone in a copy of a run folder**: the stage's data, outputs and checkpoints removed from a
  copy of the experiment's quick run (seed 3), the stage run by itself (its needs read from the
  folder) writes what the whole run wrote: the same data, the same controller files (but for the
  code's identity they record).
- **Deterministic, and resumed after an interruption**: the outside experiment killed in the
  middle of its DE and resumed gives the results of a run never stopped.

CI runs the battery for the outside experiment and for the stages of the reproduction that
take seconds (``multiplier``, ``im``, ``pm``) on the session's quick run; the other experiments'
quick runs (2-5 min each) and stages run with ``pytest -m slow``.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from mbn.experiments.pipeline import RunDir
from mbn.experiments.pipeline.reuse import stage_checkpoints
from mbn.experiments.pipeline.runner import run_stage
from mbn.experiments.registry import find, registered
from tests.conftest import kill_when_written, once

SPHERE = Path(__file__).parents[2] / "docs" / "examples" / "sphere_demo.py"
#: The stages of the reproduction CI runs alone (seconds each on the session's quick run).
IN_CI = {("reproduce", "multiplier"), ("reproduce", "im"), ("reproduce", "pm")}


def _outside(tmp_path_factory) -> str:
    folder = tmp_path_factory.mktemp("lab")
    path = folder / "sphere_demo.py"
    path.write_text(SPHERE.read_text())
    return f"{path}:EXPERIMENT"


def _cases() -> list:
    cases = []
    for name, registration in registered().items():
        for stage in registration.load().registry:
            marks = () if (name, stage.name) in IN_CI else (pytest.mark.slow,)
            cases.append(pytest.param(name, stage.name, marks=marks, id=f"{name}-{stage.name}"))
    cases.append(pytest.param("outside", "sphere", id="outside-sphere"))
    return cases


def _quick(argv: list[str], out: Path) -> None:
    command = [sys.executable, "-m", "mbn", *argv, "--quick", "--seed", "3"]
    proc = subprocess.run(
        [*command, "--out", str(out), "--quiet"],
        capture_output=True,
        text=True,
        timeout=1800,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]


@pytest.fixture(scope="session")
def outside_ref(tmp_path_factory) -> str:
    return _outside(tmp_path_factory)


@pytest.fixture
def made_run(request, tmp_path_factory, worker_id, outside_ref):
    """``name -> (folder, reference)``: the experiment's quick run of seed 3, made once per
    session (the reproduction's is the session's quick run)."""

    def get(name: str) -> tuple[Path, str]:
        if name == "reproduce":  # the session's, asked for only here (it takes minutes)
            return request.getfixturevalue("quick_run")[0], "reproduce"
        ref = outside_ref if name == "outside" else name
        argv = ["run", ref]

        def build(folder: Path) -> str:
            _quick(argv, folder / "run")
            return str(folder / "run")

        return Path(once(tmp_path_factory, worker_id, f"battery-{name}", build)), ref

    return get


@pytest.mark.parametrize(("experiment", "stage"), _cases())
def test_each_stage_runs_alone_in_a_copy_of_its_run(made_run, tmp_path, experiment, stage):
    source, ref = made_run(experiment)
    exp = find(ref).load()
    folder = tmp_path / "run"
    shutil.copytree(source, folder)
    rundir = RunDir(folder)
    manifest = rundir.read_manifest()
    config = exp.config_from_dict(manifest["config"], str(rundir.manifest))
    before = rundir.read_stage(stage)
    outputs = {rel: (folder / rel).read_bytes() for rel in exp.registry[stage].outputs}
    rundir.stage_file(stage).unlink()
    for rel in outputs:
        (folder / rel).unlink()
    for path in stage_checkpoints(rundir, stage, list(exp.registry.names)):
        path.unlink()
    data = run_stage(exp, rundir, stage, seed=manifest["seed"], config=config)
    assert json.loads(json.dumps(exp.registry[stage].to_json(data))) == before
    assert rundir.read_stage(stage) == before
    for rel, content in outputs.items():
        assert (folder / rel).exists(), rel
        if rel.startswith("controllers/"):
            assert _without_code((folder / rel).read_bytes()) == _without_code(content), rel


@pytest.mark.parametrize(("experiment", "stage"), _cases())
def test_each_stage_reads_its_data_back_as_it_wrote_it(made_run, experiment, stage):
    """A stage's typed result (its ``result`` record) read from its file and written again
    gives the file's JSON key for key, in the same order: the record declares every key the
    stage writes, and nothing is lost on the way."""
    source, ref = made_run(experiment)
    spec = find(ref).load().registry[stage]
    written = RunDir(source).read_stage(stage)
    data = spec.from_json(written, f"{source}/stages/{stage}.json")
    if spec.result is not None:
        assert isinstance(data, spec.result)
    assert json.dumps(spec.to_json(data)) == json.dumps(written)


def _without_code(content: bytes) -> dict:
    """A controller file's content without the code's identity it records (the package hash
    and commit: the code may have been edited since the run was made)."""
    data = json.loads(content)
    data.get("provenance", {}).pop("code", None)
    return data


# slow: a kill mid-stage is in CI for the pipeline (test_reproduce.py, a quick run killed and
# resumed) and an outside experiment's resume (test_registry.py, stopped between its stages)
@pytest.mark.slow
def test_an_outside_experiment_interrupted_and_resumed_gives_the_same_results(
    tmp_path, outside_ref
):
    """Killed while its DE runs (the first checkpoint written), then ``--resume``: the results
    of the run never stopped, float for float; a second run of the same seed gives them too."""
    settings = tmp_path / "long.toml"
    settings.write_text("[sphere]\ngenerations = 600\n")  # about 3 s of DE: time to kill it
    argv = ["run", outside_ref, "--config", str(settings), "--seed", "5", "--quiet"]
    base = [sys.executable, "-m", "mbn", *argv]
    stopped, whole, again = tmp_path / "stopped", tmp_path / "whole", tmp_path / "again"
    kill_when_written(
        [*base, "--out", str(stopped)], [stopped / "checkpoints" / "sphere.npz"], timeout=300
    )
    assert not (stopped / "results.json").exists()
    for out, extra in ((stopped, ["--resume"]), (whole, []), (again, [])):
        proc = subprocess.run(
            [*base, "--out", str(out), *extra], capture_output=True, text=True, timeout=600
        )
        assert proc.returncode == 0, proc.stderr[-2000:]
    results = [json.loads((f / "results.json").read_text()) for f in (stopped, whole, again)]
    for r in results:
        r.pop("code")
    assert results[0]["stages"] == results[1]["stages"] == results[2]["stages"]
    assert results[0]["tests"] == results[1]["tests"]
