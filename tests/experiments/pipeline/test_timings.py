"""``timings.json`` records the robot-steps each stage counted beside its seconds (a resumed run
keeps the earlier stages', a stage taken from another run has neither), and the table printed
at the end of ``mbn run`` and ``mbn reproduce`` shows each stage's seconds and robot-steps per
second from it (``–`` where no robot-step was counted), or nothing with ``--quiet``."""

from __future__ import annotations

import io
import json
import time
from typing import Any

import pytest

from mbn.cli.main import main
from mbn.experiments.pipeline import (
    Experiment,
    Registry,
    RunDir,
    Stage,
    StageContext,
    run_experiment,
)
from mbn.experiments.pipeline.reuse import read_source
from mbn.experiments.pipeline.timings import print_run_timings, run_rows
from mbn.world.rollout import count_robot_steps

#: The robot-steps each toy stage counts, as a rollout launch does.
STEPS = {"walk": 2_000_000, "idle": 0, "sprint": 5_500_000}
#: How long each toy stage lasts (long enough for a time that does not round to 0 s).
SLEEP_S = 0.03
RUNS: dict[str, int] = {}


class _Counting(Stage):
    """Counts its robot-steps (:data:`STEPS`) and takes :data:`SLEEP_S`."""

    def run(self, ctx: StageContext) -> dict[str, Any]:
        RUNS[self.name] = RUNS.get(self.name, 0) + 1
        count_robot_steps(STEPS[self.name])
        time.sleep(SLEEP_S)
        return {}


class Walk(_Counting):
    name, key_id = "walk", 1


class Idle(_Counting):
    name, key_id, needs = "idle", 2, ("walk",)


class Sprint(_Counting):
    name, key_id, needs = "sprint", 3, ("idle",)


def _report(rundir: RunDir) -> None:
    (rundir.root / "report.md").write_text("# toy\n")


TOY = Experiment(
    "toy",
    "mbn.toy",
    Registry([Walk(), Idle(), Sprint()]),
    results=lambda rundir, stages, config: {"claims": [{"pass": True}]},
    report=_report,
)


def _timings(folder) -> dict[str, Any]:
    return json.loads((folder / "timings.json").read_text())


def test_timings_record_the_robot_steps_each_stage_counted(tmp_path):
    run_experiment(TOY, tmp_path / "run", seed=0, config=TOY.config(), log=lambda _m: None)
    data = _timings(tmp_path / "run")
    assert list(data) == ["stages", "robot_steps", "total_seconds", "total_robot_steps"]
    assert list(data["stages"]) == ["walk", "idle", "sprint", "report"]
    assert data["robot_steps"] == {**STEPS, "report": 0}
    assert data["total_robot_steps"] == 7_500_000
    assert all(data["stages"][name] >= SLEEP_S - 0.01 for name in STEPS)
    assert data["total_seconds"] == round(sum(data["stages"].values()), 2)


def test_a_resumed_run_keeps_the_earlier_stages_entries(tmp_path):
    folder = tmp_path / "run"
    RUNS.clear()
    run_experiment(TOY, folder, seed=0, config=TOY.config(), stages=["walk"], log=print)
    first = _timings(folder)
    assert first["robot_steps"] == {"walk": 2_000_000} and list(first["stages"]) == ["walk"]
    run_experiment(TOY, folder, seed=0, config=TOY.config(), resume=True, log=print)
    data = _timings(folder)
    assert RUNS == {"walk": 1, "idle": 1, "sprint": 1}
    assert data["stages"]["walk"] == first["stages"]["walk"]
    assert data["robot_steps"] == {**STEPS, "report": 0}
    # a file written before robot_steps existed: the kept stages have seconds only
    (folder / "stages" / "sprint.json").unlink()
    (folder / "timings.json").write_text(json.dumps({"stages": {"walk": 1.5, "idle": 0.5}}))
    run_experiment(TOY, folder, seed=0, config=TOY.config(), resume=True, log=print)
    data = _timings(folder)
    assert data["stages"]["walk"] == 1.5 and data["stages"]["idle"] == 0.5
    assert data["robot_steps"] == {"sprint": 5_500_000, "report": 0}
    assert data["total_robot_steps"] == 5_500_000


def test_a_stage_taken_from_another_run_has_no_entry(tmp_path):
    run_experiment(TOY, tmp_path / "a", seed=0, config=TOY.config(), stages=["walk"], log=print)
    source = read_source(tmp_path / "a", lambda kind: TOY)
    run_experiment(TOY, tmp_path / "b", seed=0, config=TOY.config(), reuse=source, log=print)
    data = _timings(tmp_path / "b")
    assert list(data["stages"]) == ["idle", "sprint", "report"]
    assert data["robot_steps"] == {"idle": 0, "sprint": 5_500_000, "report": 0}


def _hand_made(folder) -> RunDir:
    rundir = RunDir(folder)
    rundir.create()
    rundir.write_timings(
        {"multiplier": 0.5, "rf": 86.25, "report": 3.0},
        {"multiplier": 0, "rf": 363_200_000, "report": 0},
    )
    return rundir


def test_the_table_shows_each_stages_seconds_and_rate(tmp_path):
    rundir = _hand_made(tmp_path / "run")
    assert run_rows(rundir) == [
        ["multiplier", "0.50", "0.0 M", "–"],
        ["rf", "86.25", "363.2 M", "4.21 M/s"],  # 363.2e6 / 86.25 s
        ["report", "3.00", "0.0 M", "–"],
        ["total", "89.75", "363.2 M", "4.05 M/s"],  # 363.2e6 / 89.75 s
    ]
    stream = io.StringIO()
    assert print_run_timings(rundir, stream=stream)  # not a terminal: plain text
    assert stream.getvalue().splitlines() == [
        f"time and robot-steps per stage ({rundir.timings}):",
        "  stage       seconds  robot-steps  robot-steps/s",
        "  multiplier     0.50        0.0 M              –",
        "  rf            86.25      363.2 M       4.21 M/s",
        "  report         3.00        0.0 M              –",
        "  " + "-" * 47,
        "  total         89.75      363.2 M       4.05 M/s",
    ]
    fancy = io.StringIO()
    assert print_run_timings(rundir, stream=fancy, use_rich=True)
    rows = [line for line in fancy.getvalue().splitlines() if "│" in line]
    assert any("rf" in r and "86.25" in r and "363.2 M" in r and "4.21 M/s" in r for r in rows)
    assert any("multiplier" in r and r.rstrip(" │").endswith("–") for r in rows)


def test_a_stage_without_robot_steps_or_time_shows_no_rate(tmp_path):
    folder = tmp_path / "run"
    folder.mkdir()
    # written before robot_steps existed: no figure, no rate
    (folder / "timings.json").write_text(json.dumps({"stages": {"rf": 10.0}}))
    assert run_rows(RunDir(folder)) == [
        ["rf", "10.00", "–", "–"],
        ["total", "10.00", "–", "–"],
    ]
    RunDir(folder).write_timings({"rf": 0.0}, {"rf": 1_000_000})  # rounded to 0 s
    assert run_rows(RunDir(folder))[0] == ["rf", "0.00", "1.0 M", "–"]
    (folder / "timings.json").unlink()
    stream = io.StringIO()
    assert not print_run_timings(RunDir(folder), stream=stream) and stream.getvalue() == ""


def _expected_rows(folder) -> list[tuple[str, str, str, str]]:
    """The table's rows as the run's own timings.json gives them, worked out here."""
    data = _timings(folder)
    rows = []
    for name, secs in data["stages"].items():
        steps = data["robot_steps"][name]
        rate = f"{steps / secs / 1e6:.2f} M/s" if steps and secs > 0 else "–"
        rows.append((name, f"{secs:.2f}", f"{steps / 1e6:.1f} M", rate))
    return rows


@pytest.mark.parametrize("command", ["run", "reproduce"])
def test_the_commands_print_the_table_at_the_end_and_not_with_quiet(
    tmp_path, capsys, monkeypatch, command
):
    import mbn.cli.run as run_cli
    import mbn.experiments.reproduce as reproduce

    monkeypatch.setattr(run_cli, "experiment", lambda name: TOY)
    monkeypatch.setattr(reproduce, "REPRODUCE", TOY)
    argv = ["run", "noise"] if command == "run" else ["reproduce"]
    out = tmp_path / "run"
    assert main([*argv, "--out", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    start = lines.index(f"time and robot-steps per stage ({out / 'timings.json'}):")
    table = [line.split() for line in lines[start + 1 :]]
    assert table[0] == ["stage", "seconds", "robot-steps", "robot-steps/s"]
    for name, secs, steps, rate in _expected_rows(out):
        row = next(r for r in table if r[0] == name)
        assert row == [name, secs, *steps.split(), *rate.split()]
    assert next(r for r in table if r[0] == "idle")[-1] == "–"
    assert next(r for r in table if r[0] == "walk")[-1] == "M/s"
    total = next(r for r in table if r[0] == "total")
    assert total[2:4] == ["7.5", "M"]
    # the command's last line stays its own
    assert lines[-1].startswith("results: " if command == "run" else "1 of 1 claims hold")
    assert main([*argv, "--out", str(tmp_path / "quiet"), "--quiet"]) == 0
    assert capsys.readouterr().out == ""
