"""The time each stage of a run took and the robot-steps per second it reached, as a table: read
back from the run's ``timings.json`` and printed at the end of ``mbn reproduce`` and ``mbn run``
(the sweep's, over its seeds: :mod:`mbn.experiments.sweep.timings`).

``timings.json`` (:meth:`~mbn.experiments.pipeline.rundir.RunDir.write_timings`; which stages
have entries: :mod:`~mbn.experiments.pipeline.runner`)::

    {"stages": {"rf": 812.4, ...}, "robot_steps": {"rf": 3420100000, ...},
     "total_seconds": 2031.0, "total_robot_steps": 8120300000}

A row per stage of ``stages``, in its order: seconds, robot-steps (millions: ``363.2 M``) and
robot-steps per second (``4.21 M/s``), then a total row (the rate: every robot-step counted over
the run's whole time). A stage without a ``robot_steps`` entry (a file written before the field
existed) shows ``–`` for its robot-steps; a stage that counted none, or whose time rounds to
0 s, shows ``–`` for its rate. On a terminal the table is rich's; elsewhere (a log file, a pipe)
plain text aligned in columns.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import TextIO

from mbn.experiments.pipeline.rundir import RunDir

__all__ = [
    "RUN_HEADER",
    "clock",
    "millions",
    "print_run_timings",
    "print_table",
    "rate",
    "run_rows",
    "seconds",
]

#: The columns of a run's table.
RUN_HEADER = ("stage", "seconds", "robot-steps", "robot-steps/s")
#: What a cell without a value shows.
NONE = "–"


def clock(secs: float) -> str:
    """A duration as a person reads it: ``45 s``, ``2 min 05 s``, ``1 h 02 min``."""
    m, s = divmod(round(secs), 60)
    h, m = divmod(m, 60)
    return f"{h} h {m:02d} min" if h else (f"{m} min {s:02d} s" if m else f"{s} s")


def seconds(value: float | None) -> str:
    """``812.40``; ``–`` for None."""
    return NONE if value is None else f"{value:.2f}"


def millions(steps: int | None) -> str:
    """Robot-steps in millions, ``363.2 M``; ``–`` for None (not recorded)."""
    return NONE if steps is None else f"{steps / 1e6:,.1f} M"


def rate(steps: int | None, secs: float | None) -> str:
    """Robot-steps per second in millions, ``4.21 M/s``; ``–`` where no robot-step was counted
    or no time measured (a time that rounds to 0 s)."""
    if not steps or secs is None or secs <= 0:
        return NONE
    return f"{steps / secs / 1e6:,.2f} M/s"


def run_rows(rundir: RunDir) -> list[list[str]]:
    """The rows of the run in ``rundir`` (:data:`RUN_HEADER`), from its ``timings.json``: one per
    stage and a total row; empty where the file records no stage."""
    times = rundir.read_timings()
    if not times:
        return []
    counted = rundir.read_robot_steps()
    rows = [
        [name, seconds(t), millions(counted.get(name)), rate(counted.get(name), t)]
        for name, t in times.items()
    ]
    total_s = round(sum(times.values()), 2)
    total_n = sum(counted.values()) if counted else None
    rows.append(["total", seconds(total_s), millions(total_n), rate(total_n, total_s)])
    return rows


def print_table(
    title: str,
    header: Sequence[str],
    rows: Sequence[Sequence[str]],
    *,
    stream: TextIO | None = None,
    use_rich: bool | None = None,
    footer: str | None = None,
) -> None:
    """Print a table of text cells (at least one row) to ``stream`` (default stdout): the first
    column left-aligned, the others right-aligned, the last row (a total) set apart by a rule,
    then ``footer`` where given. ``use_rich``: rich's table (default: where ``stream`` is a
    terminal); otherwise plain text for a log file: ``title:``, then the rows indented by two
    spaces, columns two spaces apart."""
    out = sys.stdout if stream is None else stream
    if use_rich is None:
        use_rich = out.isatty()
    if use_rich:
        from rich.console import Console
        from rich.table import Table

        table = Table()
        for k, name in enumerate(header):
            table.add_column(name, justify="left" if k == 0 else "right")
        for k, row in enumerate(rows):
            table.add_row(*row, end_section=k == len(rows) - 2)
        console = Console(file=out, highlight=False)
        console.print(title, markup=False)
        console.print(table)
        if footer:
            console.print(footer, markup=False)
        return
    widths = [max(len(r[k]) for r in [header, *rows]) for k in range(len(header))]

    def line(cells: Sequence[str]) -> str:
        first = cells[0].ljust(widths[0])
        rest = [c.rjust(w) for c, w in zip(cells[1:], widths[1:], strict=True)]
        return "  " + "  ".join([first, *rest])

    rule = "  " + "-" * (sum(widths) + 2 * (len(widths) - 1))
    text = [f"{title}:", line(header), *(line(r) for r in rows[:-1]), rule, line(rows[-1])]
    if footer:
        text.append(footer)
    out.write("\n".join(text) + "\n")
    out.flush()


def print_run_timings(
    rundir: RunDir, *, stream: TextIO | None = None, use_rich: bool | None = None
) -> bool:
    """Print the table of the run in ``rundir`` (module docstring); returns whether there was
    one (nothing is printed for a ``timings.json`` that records no stage, or none at all)."""
    rows = run_rows(rundir)
    if not rows:
        return False
    title = f"time and robot-steps per stage ({rundir.timings})"
    print_table(title, RUN_HEADER, rows, stream=stream, use_rich=use_rich)
    return True
