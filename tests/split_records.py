"""A generalization split's record as a run writes it (``SplitRecord``), built from the
successes of each maze's trials, for tests of what reads it (the targets, the sweep)."""

from __future__ import annotations

from mbn.experiments.generalization import Failures, MazeRow, Pooled, SplitRecord


def split_record_of(successes: list[int], trials: int = 10) -> SplitRecord:
    """One maze per entry of ``successes``, each of ``trials`` trials; the failed trials
    counted as stalls. ``meets_targets`` is left False: readers judge from the figures."""
    total, n = sum(successes), trials * len(successes)
    at = sum(s * 100 >= 95 * trials for s in successes)
    return SplitRecord(
        mazes=[
            MazeRow(maze=f"m{k}", trials=trials, successes=s, timed_out=0)
            for k, s in enumerate(successes)
        ],
        pooled=Pooled(
            trials=n, successes=total, timed_out=0, success_rate=total / n, wilson95=[0.0, 1.0]
        ),
        mazes_at_95=at,
        fraction_of_mazes_at_95=at / len(successes),
        seconds=60.0,
        failures=Failures(failed=n - total, wrong_exit=0, stalled=n - total, timed_out=0),
        meets_targets=False,
    )
