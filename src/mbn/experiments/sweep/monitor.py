"""The progress of a sweep: a table of seeds x stages, read from the seed folders.

A stage of a seed is *done* when ``stages/NAME.json`` exists (its time from ``timings.json``),
*running* when it is the first stage not done of a seed whose task has started (a file of its
folder was written since the task was submitted; its time counted from the later of that moment
and the last stage that ended), *failed* when that seed's run crashed, and *waiting* otherwise.

On a terminal the table is live (rich); elsewhere every change is one plain line.
"""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TextIO

from mbn.experiments.sweep.run import seed_dir
from mbn.io import read_json

__all__ = ["SweepMonitor", "stage_states"]


def _latest_write(folder: Path) -> float:
    """The latest modification time of the files a run writes as it goes (0 if none)."""
    latest = 0.0
    for pattern in ("run.json", "timings.json", "stages/*.json", "checkpoints/*.npz"):
        for p in folder.glob(pattern):
            with contextlib.suppress(OSError):
                latest = max(latest, p.stat().st_mtime)
    return latest


def _timings(folder: Path) -> dict[str, float]:
    path = folder / "timings.json"
    try:
        data = read_json(path)
        return {str(k): float(v) for k, v in data.get("stages", {}).items()}
    except Exception:  # being written, or absent: no times yet
        return {}


def stage_states(
    folder: Path, stages: Sequence[str], task: str, started: float | None, now: float
) -> list[tuple[str, float | None]]:
    """``(state, seconds)`` of each stage of the run in ``folder``, given its task's state
    (``waiting``, ``queued``, ``running``, ``done``, ``failed``) and when it was seen to start."""
    times = _timings(folder)
    out: list[tuple[str, float | None]] = []
    current = True
    for name in stages:
        path = folder / "stages" / f"{name}.json"
        if path.exists():
            out.append(("done", times.get(name)))
            continue
        if current and task == "running":
            since = started or now
            ended = [p.stat().st_mtime for p in (folder / "stages").glob("*.json") if p.exists()]
            if ended:
                since = max(since, max(ended))
            out.append(("running", max(0.0, now - since)))
        elif current and task == "failed":
            out.append(("failed", None))
        else:
            out.append(("waiting", None))
        current = False
    return out


_STYLE = {
    "done": "green",
    "running": "yellow",
    "failed": "bold red",
    "waiting": "dim",
    "queued": "dim",
}


class SweepMonitor:
    """Seeds x stages, live on a terminal (``live=True``), else as plain lines on ``stream``."""

    def __init__(
        self,
        out: Path,
        seeds: Sequence[int],
        stages: Sequence[str],
        *,
        live: bool,
        stream: TextIO | None = None,
    ) -> None:
        self.out = Path(out)
        self.seeds = list(seeds)
        self.stages = list(stages)
        self.live = live
        self.stream = stream or sys.stdout
        self.task: dict[int, str] = dict.fromkeys(self.seeds, "waiting")
        self.submitted: dict[int, float] = {}
        self.started: dict[int, float] = {}
        self.errors: dict[int, str] = {}
        self._shown: dict[int, list[str]] = {}
        self._live: Any = None
        self.t0 = time.time()

    def __enter__(self) -> SweepMonitor:
        if self.live:
            from rich.console import Console
            from rich.live import Live

            self._live = Live(
                self._table(),
                console=Console(file=self.stream),
                refresh_per_second=2,
                transient=False,
            )
            self._live.__enter__()
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._live is not None:
            self._live.update(self._table())
            self._live.__exit__(*exc)
            self._live = None

    def mark(self, seed: int, state: str, error: str | None = None) -> None:
        """The task of ``seed`` is ``waiting``, ``queued``, ``done`` or ``failed``."""
        if state == "queued":
            self.submitted[seed] = time.time()
        self.task[seed] = state
        if error:
            self.errors[seed] = error
        if not self.live and state in ("done", "failed") and seed in self.submitted:
            self._print_changes(seed)
            if state == "failed":
                print(f"seed {seed}: failed: {error}", file=self.stream, flush=True)
            else:
                print(f"seed {seed}: done", file=self.stream, flush=True)
        self.poll()

    def poll(self) -> None:
        """Read the seed folders again and show what changed."""
        now = time.time()
        for s in self.seeds:
            if self.task[s] == "queued":
                folder = seed_dir(self.out, s)
                if _latest_write(folder) >= self.submitted[s] - 1:
                    self.task[s] = "running"
                    self.started[s] = now
            if not self.live and self.task[s] == "running":
                self._print_changes(s)
        if self._live is not None:
            self._live.update(self._table())

    def _states(self, seed: int, now: float) -> list[tuple[str, float | None]]:
        return stage_states(
            seed_dir(self.out, seed), self.stages, self.task[seed], self.started.get(seed), now
        )

    def _print_changes(self, seed: int) -> None:
        states = self._states(seed, time.time())
        shown = self._shown.setdefault(seed, ["waiting"] * len(self.stages))
        for k, (state, secs) in enumerate(states):
            if state != shown[k] and state in ("running", "done"):
                what = f"done ({secs:.0f} s)" if state == "done" and secs is not None else state
                print(f"seed {seed}: {self.stages[k]} {what}", file=self.stream, flush=True)
                shown[k] = state

    def _table(self) -> Any:
        from rich.table import Table

        now = time.time()
        table = Table(title=f"mbn sweep: {self.out}  ({_clock(now - self.t0)})")
        table.add_column("seed", justify="right")
        for name in self.stages:
            table.add_column(name)
        table.add_column("run")
        for s in self.seeds:
            cells = []
            for state, secs in self._states(s, now):
                text = state if secs is None else f"{state} {_clock(secs)}"
                cells.append(f"[{_STYLE[state]}]{text}[/]")
            run = self.task[s]
            if run == "failed":
                run = f"failed: {self.errors.get(s, '')}"[:60]
            table.add_row(str(s), *cells, f"[{_STYLE.get(self.task[s], 'default')}]{run}[/]")
        return table


def _clock(seconds: float) -> str:
    seconds = round(seconds)
    if seconds < 60:
        return f"{seconds} s"
    return f"{seconds // 60}:{seconds % 60:02d}"
