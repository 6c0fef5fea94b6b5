"""Progress without a terminal (plain-line mode): a line at least every 30 s of a long stage,
naming the stage, the task (a DE's generation) and its best fitness, and not more often; a line
when a long task finishes. With a fake clock, and through the runner with a short interval."""

from __future__ import annotations

import time
from typing import Any

from mbn.experiments.pipeline import Experiment, Registry, Stage, StageContext, run_experiment
from mbn.experiments.pipeline import progress as progress_module
from mbn.experiments.pipeline.progress import PLAIN_INTERVAL, Progress


class Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def _plain(clock: Clock) -> tuple[Progress, list[str]]:
    lines: list[str] = []
    return Progress(False, lines=lines.append, clock=clock, heartbeat=False), lines


def test_a_long_de_prints_one_line_per_interval_with_stage_generation_and_best():
    assert PLAIN_INTERVAL == 30.0
    clock = Clock()
    bars, lines = _plain(clock)
    with bars:
        bars.stage("rf")
        overall = bars.task("mbn reproduce", 8, quiet=True)
        bar = bars.task("RF: DE generations", 300)
        for g in range(1, 200):  # 2 s a generation: 398 s
            clock.now += 2.0
            bars.update(bar, completed=g, info=f"best {g / 10:.2f}")
            bars.update(overall, completed=1, info="rf")
    assert len(lines) == 398 // 30  # at least one every 30 s, and no more
    assert lines[0] == "stage rf: RF: DE generations 15/300, best 1.50; 30 s into the stage"
    assert all(line.startswith("stage rf: RF: DE generations ") for line in lines)
    assert all("mbn reproduce" not in line for line in lines)  # the run's bar has no line


def test_a_line_comes_while_a_long_generation_runs_and_not_twice():
    clock = Clock()
    bars, lines = _plain(clock)
    bars.stage("lf")
    bar = bars.task("LF: DE generations", 70)
    bars.update(bar, completed=3, info="best 8.04")
    clock.now += 29.0
    bars.tick()
    assert lines == []
    clock.now += 2.0  # one generation longer than the interval: the heartbeat's tick says so
    bars.tick()
    bars.tick()
    assert lines == ["stage lf: LF: DE generations 3/70, best 8.04; 31 s into the stage"]
    clock.now += 30.0
    bars.tick()
    assert len(lines) == 2 and lines[1].endswith("; 1 min 01 s into the stage")


def test_a_long_task_says_it_finished_a_short_one_does_not():
    clock = Clock()
    bars, lines = _plain(clock)
    bars.stage("tests")
    short = bars.task("tests", 3)
    for b in range(1, 4):
        clock.now += 1.0
        bars.update(short, completed=b, info="batch")
    assert lines == []
    long = bars.task("PM: DE generations", 2)
    clock.now += 29.0
    bars.update(long, completed=1, info="best -0.1")
    clock.now += 2.0
    bars.update(long, completed=2, info="best -0.05")
    assert lines == [
        "stage tests: PM: DE generations 1/2, best -0.1; 32 s into the stage",
        # the line a finish adds, though the last came 2 s before
        "stage tests: PM: DE generations 2/2, best -0.05; 34 s into the stage",
    ]
    # a stage that runs on after its tasks says what it ran last
    clock.now += 31.0
    bars.tick()
    assert lines[-1] == (
        "stage tests: running on after PM: DE generations 2/2, best -0.05; 1 min 05 s into "
        "the stage"
    )
    # between stages, and with no stage, nothing is said
    bars.stage(None)
    clock.now += 100.0
    bars.tick()
    assert len(lines) == 3


def test_a_stage_without_a_task_still_says_it_runs():
    clock = Clock()
    bars, lines = _plain(clock)
    bars.stage("report")
    clock.now += 45.0
    bars.tick()
    assert lines == ["stage report: running; 45 s into the stage"]


def test_bars_or_silence_print_no_plain_line():
    clock = Clock()
    silent = Progress(False, clock=clock, heartbeat=False)
    silent.stage("rf")
    assert silent.task("RF", 10) is None and not silent.plain
    lines: list[str] = []
    with_bars = Progress(True, lines=lines.append, clock=clock, heartbeat=False)
    assert not with_bars.plain


class SlowStage(Stage):
    """A DE of 4 slow generations, each longer than the (shortened) interval."""

    name = "slow"
    key_id = 44

    def run(self, ctx: StageContext) -> dict[str, Any]:
        bar = ctx.progress.task("SLOW: DE generations", 4)
        for g in range(1, 5):
            time.sleep(0.25)
            ctx.progress.update(bar, completed=g, info=f"best {g:.2f}")
        return {"done": True}


def test_the_runner_prints_plain_lines_of_a_long_stage(tmp_path, monkeypatch):
    monkeypatch.setattr(progress_module, "PLAIN_INTERVAL", 0.2)
    experiment = Experiment(name="slow", kind="mbn.slow", registry=Registry([SlowStage()]))
    lines: list[str] = []
    t0 = time.monotonic()
    run_experiment(
        experiment, tmp_path / "run", seed=0, config=experiment.config(), log=lines.append
    )
    seconds = time.monotonic() - t0
    plain = [line for line in lines if "into the stage" in line]
    assert plain and all(line.startswith("stage slow: ") for line in plain)
    assert any(line.startswith("stage slow: SLOW: DE generations ") for line in plain)
    assert any(", best " in line for line in plain)
    assert lines[-1] == "stage slow: done"
    # one line per interval at most, and one more when the DE finishes
    assert len(plain) <= seconds / 0.2 + 1
