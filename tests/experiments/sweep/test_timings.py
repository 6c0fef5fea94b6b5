"""The sweep's table of stage times: per stage the median and max seconds over the seeds that ran
it and the robot-steps per second over all of them, from each seed's ``timings.json`` (built by
hand here), and the sweep's wall time."""

from __future__ import annotations

import io
import json

from mbn.experiments.pipeline import RunDir
from mbn.experiments.sweep.run import seed_dir
from mbn.experiments.sweep.timings import print_sweep_timings, stage_times, sweep_rows


def _seed(out, seed: int, seconds: dict[str, float], steps: dict[str, int] | None) -> None:
    rundir = RunDir(seed_dir(out, seed))
    rundir.create()
    if steps is None:  # a file written before robot_steps existed
        rundir.timings.write_text(json.dumps({"stages": seconds}))
    else:
        rundir.write_timings(seconds, steps)


def _sweep(tmp_path):
    out = tmp_path / "sweep"
    _seed(out, 0, {"rf": 100.0, "lf": 10.0, "report": 2.0}, {"rf": 400_000_000, "lf": 0})
    _seed(
        out,
        1,
        {"rf": 300.0, "lf": 30.0, "report": 4.0},
        {"rf": 1_200_000_000, "lf": 50_000_000, "report": 0},
    )
    _seed(out, 3, {"rf": 500.0}, None)  # seconds only
    (seed_dir(out, 4)).mkdir()  # no timings.json: left out (as seed 2, which has no folder)
    return out


def test_two_seeds_are_summed_up_per_stage(tmp_path):
    out = _sweep(tmp_path)
    stages, whole = stage_times(out, [0, 1, 2, 3, 4])
    rf = stages[0]
    assert [s.name for s in stages] == ["rf", "lf", "report"]
    assert rf.seconds == [100.0, 300.0, 500.0]
    # the rate only over the seeds that recorded robot-steps: 1.6e9 over 400 s
    assert rf.robot_steps == 1_600_000_000 and rf.counted_seconds == 400.0
    assert whole.seconds == [112.0, 334.0, 500.0] and whole.robot_steps == 1_650_000_000
    assert sweep_rows(out, [0, 1, 2, 3, 4]) == [
        ["rf", "3", "300.00", "500.00", "4.00 M/s"],
        ["lf", "2", "20.00", "30.00", "1.25 M/s"],  # 5e7 / 40 s
        ["report", "2", "3.00", "4.00", "–"],  # seed 0 recorded none for it, seed 1 zero
        ["all stages", "3", "334.00", "500.00", "3.70 M/s"],  # 1.65e9 / 446 s
    ]


def test_the_printed_table_ends_with_the_wall_time(tmp_path):
    out = _sweep(tmp_path)
    stream = io.StringIO()
    assert print_sweep_timings(out, [0, 1, 2, 3, 4], 725.4, stream=stream)
    lines = stream.getvalue().splitlines()
    assert lines[0] == f"time and robot-steps per stage over the seeds ({out}):"
    assert lines[1].split() == ["stage", "seeds", "median", "s", "max", "s", "robot-steps/s"]
    assert lines[2].split() == ["rf", "3", "300.00", "500.00", "4.00", "M/s"]
    assert set(lines[-3].strip()) == {"-"}
    assert lines[-2].split() == ["all", "stages", "3", "334.00", "500.00", "3.70", "M/s"]
    assert lines[-1] == "sweep wall time: 12 min 05 s (725.4 s)"
    fancy = io.StringIO()
    assert print_sweep_timings(out, [0, 1], None, stream=fancy, use_rich=True)
    text = fancy.getvalue()
    assert "│ lf " in text and "1.25 M/s" in text and "wall time" not in text


def test_no_seed_with_timings_prints_nothing(tmp_path):
    stream = io.StringIO()
    assert not print_sweep_timings(tmp_path, [0, 1], 10.0, stream=stream)
    assert stream.getvalue() == ""
