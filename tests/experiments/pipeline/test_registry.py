"""Adding a stage is one module and one registry line: a toy stage in a temporary registry runs
through the runner (settings, key, resume, results.json, timings), and the registry refuses
inconsistent stages."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import jax
import numpy as np
import pytest

from mbn.config import Settings, read_toml, setting
from mbn.errors import MbnInputError
from mbn.experiments.pipeline import Experiment, Registry, Stage, StageContext, run_experiment
from mbn.precision import scope


@dataclass(frozen=True)
class ToySettings(Settings):
    """A toy stage's settings."""

    section = "toy"
    draws: int = setting(3, doc="numbers drawn", low=1)


class ToyStage(Stage):
    """Draws ``draws`` uniform numbers from its key and writes them to a record."""

    name = "toy"
    key_id = 42
    settings = ToySettings
    runs = 0

    def run(self, ctx: StageContext) -> dict[str, Any]:
        ToyStage.runs += 1
        values = np.asarray(jax.random.uniform(ctx.key, (ctx.settings.draws,)), dtype=float)
        ctx.rundir.save_record("toy", {"values": values})
        return {"values": values.tolist(), "details": "kept out of results.json"}

    def summary(self, data: dict[str, Any]) -> str:
        return f"{len(data['values'])} values"


class ToyAfter(Stage):
    name = "after"
    key_id = 43
    needs = ("toy",)

    def run(self, ctx: StageContext) -> dict[str, Any]:
        return {"total": float(sum(ctx.read("toy")["values"]))}


def _experiment(*stages: Stage) -> Experiment:
    return Experiment(name="toy", kind="mbn.toy", registry=Registry(list(stages)))


def test_a_toy_stage_in_a_temporary_registry_runs_through_the_runner(tmp_path):
    ToyStage.runs = 0
    experiment = _experiment(ToyStage(), ToyAfter())
    config = experiment.config()
    assert config["toy"].draws == 3
    lines: list[str] = []
    results = run_experiment(experiment, tmp_path / "run", seed=7, config=config, log=lines.append)
    # the stage draws from fold_in(key(seed), key_id), in the run's precision (float32)
    with scope("float32"):
        expected = np.asarray(jax.random.uniform(jax.random.fold_in(jax.random.key(7), 42), (3,)))
    np.testing.assert_allclose(results["stages"]["toy"]["values"], expected, rtol=0, atol=0)
    assert results["stages"]["after"]["total"] == pytest.approx(float(np.sum(expected)), abs=1e-6)
    assert "details" not in results["stages"]["toy"]
    assert results["config"]["toy"] == {"draws": 3} and results["seed"] == 7
    assert lines == ["stage toy: 3 values", "stage after: done"]
    folder = tmp_path / "run"
    on_disk = json.loads((folder / "results.json").read_text())
    assert on_disk == json.loads(json.dumps(results))
    # an experiment with no report of its own gets the plain one (its time recorded as any)
    assert set(json.loads((folder / "timings.json").read_text())["stages"]) == {
        "toy",
        "after",
        "report",
    }
    assert "| toy | 3 values |" in (folder / "report.md").read_text()
    assert (folder / "records" / "toy.npz").exists()
    # resuming keeps what is done: the stage does not run again, the results are the same
    again = run_experiment(experiment, folder, seed=7, config=config, resume=True, log=lines.append)
    assert ToyStage.runs == 1 and lines[-2:] == ["stage toy: done before, kept"] * 1 + [
        "stage after: done before, kept"
    ]
    assert again == results


def test_the_toy_stage_reads_its_settings_from_a_toml_file(tmp_path):
    experiment = _experiment(ToyStage())
    (tmp_path / "s.toml").write_text("[toy]\ndraws = 5\n")
    config = experiment.config(document=read_toml(tmp_path / "s.toml"))
    results = run_experiment(experiment, tmp_path / "run", seed=0, config=config, log=print)
    assert len(results["stages"]["toy"]["values"]) == 5
    (tmp_path / "bad.toml").write_text("[toy]\n\ndraws = 0\n")
    with pytest.raises(MbnInputError, match=r"bad\.toml:3: toy\.draws: must be >= 1, got 0"):
        experiment.config(document=read_toml(tmp_path / "bad.toml"))
    # a run resumed with another config is refused
    other = experiment.config()
    with pytest.raises(MbnInputError, match=r"another config \(toy\.draws: 5 then, 3 now\)"):
        run_experiment(experiment, tmp_path / "run", seed=0, config=other, resume=True)


def test_an_experiment_sets_a_library_stages_defaults_under_the_quick_preset_and_the_file(
    tmp_path,
):
    from dataclasses import replace

    experiment = replace(
        _experiment(ToyStage()), defaults={"toy": {"draws": 7}}, quick={"toy": {"draws": 2}}
    )
    assert experiment.config()["toy"].draws == 7
    assert experiment.config(quick=True)["toy"].draws == 2
    (tmp_path / "s.toml").write_text("[toy]\ndraws = 5\n")
    assert experiment.config(quick=True, document=read_toml(tmp_path / "s.toml"))["toy"].draws == 5
    assert _experiment(ToyStage()).config()["toy"].draws == 3  # the setting's own default
    with pytest.raises(MbnInputError, match=r"toy: defaults: unknown section \[tiles\]"):
        replace(experiment, defaults={"tiles": {"draws": 1}}).config()
    with pytest.raises(MbnInputError, match=r"draws: must be >= 1, got 0"):
        replace(experiment, defaults={"toy": {"draws": 0}}).config()


class _Named(Stage):
    def __init__(
        self, name: str, key_id: int, needs: tuple[str, ...] = (), result: Any = None
    ) -> None:
        self.name = name  # type: ignore[misc]
        self.key_id = key_id  # type: ignore[misc]
        self.needs = needs  # type: ignore[misc]
        self.result = result  # type: ignore[misc]

    def run(self, ctx: StageContext) -> dict[str, Any]:
        return {}


@pytest.mark.parametrize(
    ("stages", "message"),
    [
        ([_Named("a", 1), _Named("a", 2)], "used twice"),
        ([_Named("a", 1), _Named("b", 1)], "key_id 1"),
        ([_Named("a", 1, needs=("b",)), _Named("b", 2)], "do not run before it"),
        ([_Named("a", 0)], "key_id 0"),
        ([_Named("a", 1, result=dict)], "not a Record"),
    ],
)
def test_the_registry_refuses_inconsistent_stages(stages, message):
    with pytest.raises(ValueError, match=message):
        Registry(stages)


def test_a_stage_reading_an_undeclared_stage_is_a_bug(tmp_path):
    class Sneaky(Stage):
        name = "sneaky"
        key_id = 44

        def run(self, ctx: StageContext) -> dict[str, Any]:
            return ctx.read("toy")

    with pytest.raises(RuntimeError, match="does not declare it"):
        run_experiment(
            _experiment(ToyStage(), Sneaky()),
            tmp_path / "run",
            seed=0,
            config=_experiment(ToyStage(), Sneaky()).config(),
            log=lambda _m: None,
        )


def test_a_run_recorded_before_a_setting_existed_resumes_when_it_asks_for_what_the_run_did(
    tmp_path,
):
    """A ``run.json`` without a key (or a whole section) ran with the key's ``recorded_before``
    value (or the default): resuming it with a config asking for that is accepted; asking for
    another value is refused, naming it."""
    experiment = _experiment(ToyStage())
    config = experiment.config()
    folder = tmp_path / "run"
    results = run_experiment(experiment, folder, seed=1, config=config, log=lambda _: None)
    manifest = folder / "run.json"
    data = json.loads(manifest.read_text())
    assert data["config"]["toy"] == {"draws": 3}
    data["config"].pop("toy")  # recorded before the section existed: it ran with the default
    manifest.write_text(json.dumps(data))
    again = run_experiment(experiment, folder, seed=1, config=config, resume=True, log=print)
    assert again == results
    (tmp_path / "s.toml").write_text("[toy]\ndraws = 4\n")
    other = experiment.config(document=read_toml(tmp_path / "s.toml"))
    with pytest.raises(MbnInputError, match=r"another config \(toy\.draws: 3 then, 4 now\)"):
        run_experiment(experiment, folder, seed=1, config=other, resume=True)
