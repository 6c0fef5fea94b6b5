"""The time each stage took over the seeds of a sweep and the robot-steps per second it reached,
read from each seed's ``timings.json`` (:mod:`mbn.experiments.pipeline.timings`) and printed at
the end of ``mbn sweep`` with the sweep's wall time.

A row per stage, in the order the seeds' files name them: how many seeds ran it (those whose
``timings.json`` records it: a seed that took the stage from another run, ``--reuse``, did not),
the median and the max of their seconds, and the robot-steps per second over all of them (the sum
of their robot-steps over the sum of their seconds, both over the seeds that recorded
robot-steps for it: a file written before ``robot_steps`` existed counts for the seconds only).
The last row, ``all stages``, is the same over each seed's whole run (the sum of its stages).
A seed without a ``timings.json``, or with one that cannot be read, is left out.
"""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from mbn.errors import MbnInputError
from mbn.experiments.pipeline.rundir import RunDir
from mbn.experiments.pipeline.timings import clock, print_table, rate, seconds
from mbn.experiments.sweep.run import seed_dir

__all__ = ["SWEEP_HEADER", "StageTimes", "print_sweep_timings", "stage_times", "sweep_rows"]

#: The columns of a sweep's table.
SWEEP_HEADER = ("stage", "seeds", "median s", "max s", "robot-steps/s")


@dataclass
class StageTimes:
    """One stage over the seeds that ran it."""

    name: str
    #: the seconds of each seed that ran it
    seconds: list[float] = field(default_factory=list)
    #: the robot-steps of the seeds that recorded them, and those seeds' seconds
    robot_steps: int = 0
    counted_seconds: float = 0.0

    def add(self, secs: float, steps: int | None) -> None:
        """One seed's entry (``steps`` None: not recorded)."""
        self.seconds.append(secs)
        if steps is not None:
            self.robot_steps += steps
            self.counted_seconds += secs

    def row(self) -> list[str]:
        """The row of :data:`SWEEP_HEADER`."""
        return [
            self.name,
            str(len(self.seconds)),
            seconds(statistics.median(self.seconds)),
            seconds(max(self.seconds)),
            rate(self.robot_steps, round(self.counted_seconds, 2)),
        ]


def _read(folder: Path) -> tuple[dict[str, float], dict[str, int]] | None:
    """A seed's seconds and robot-steps per stage, or None without a readable ``timings.json``."""
    rundir = RunDir(folder)
    if not rundir.timings.exists():
        return None
    try:
        return rundir.read_timings(), rundir.read_robot_steps()
    except (MbnInputError, TypeError, ValueError):
        return None


def stage_times(out: Path, seeds: Sequence[int]) -> tuple[list[StageTimes], StageTimes]:
    """Per stage over the seeds of the sweep in ``out``, and the whole runs (``all stages``):
    the module docstring's rows as numbers."""
    stages: dict[str, StageTimes] = {}
    whole = StageTimes("all stages")
    for seed in seeds:
        found = _read(seed_dir(out, seed))
        if found is None or not found[0]:
            continue
        times, counted = found
        for name, secs in times.items():
            stages.setdefault(name, StageTimes(name)).add(secs, counted.get(name))
        whole.add(
            round(sum(times.values()), 2),
            sum(counted.values()) if counted else None,
        )
    return list(stages.values()), whole


def sweep_rows(out: Path, seeds: Sequence[int]) -> list[list[str]]:
    """The rows of :data:`SWEEP_HEADER` (the last: ``all stages``); empty where no seed
    recorded a stage."""
    stages, whole = stage_times(out, seeds)
    if not stages:
        return []
    return [s.row() for s in stages] + [whole.row()]


def print_sweep_timings(
    out: Path,
    seeds: Sequence[int],
    wall_seconds: float | None,
    *,
    stream: TextIO | None = None,
    use_rich: bool | None = None,
) -> bool:
    """Print the table of the sweep in ``out`` over ``seeds`` (module docstring), with its wall
    time ``wall_seconds`` (``sweep.json``'s ``seconds``: the last ``mbn sweep`` command that
    ran it) beneath; returns whether there was one (nothing is printed where no seed recorded a
    stage)."""
    rows = sweep_rows(out, seeds)
    if not rows:
        return False
    footer = None
    if wall_seconds is not None:
        footer = f"sweep wall time: {clock(wall_seconds)} ({wall_seconds:.1f} s)"
    print_table(
        f"time and robot-steps per stage over the seeds ({out})",
        SWEEP_HEADER,
        rows,
        stream=stream,
        use_rich=use_rich,
        footer=footer,
    )
    return True
