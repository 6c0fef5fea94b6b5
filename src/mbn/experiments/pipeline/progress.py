"""Progress of a run: rich progress bars (one per stage, one per DE) on a terminal, or plain lines
where there is none (a log file, a pipe, a batch job)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

__all__ = ["PLAIN_INTERVAL", "Progress"]

#: Plain-line mode: at least one line per this many seconds of a stage, and at most one more
#: (beside the lines of tasks that finish).
PLAIN_INTERVAL = 30.0


@dataclass
class _Task:
    """A task's state in plain-line mode."""

    description: str
    total: int | None
    completed: int = 0
    info: str = ""
    started: float = 0.0
    quiet: bool = False


class Progress:
    """Rich progress bars when ``enabled``; otherwise, when ``lines`` is given (plain-line
    mode), a line through ``lines`` at least every :data:`PLAIN_INTERVAL` seconds of a stage
    and not more often (``stage NAME: TASK C/T, best F; S s into the stage``, of the task last
    moved), and a line when a task that ran that long finishes; otherwise silent. The methods
    are the same in every mode.

    Used as a context manager; :meth:`task` adds a bar, :meth:`update` moves it, :meth:`stage`
    names the stage that runs. In plain-line mode a thread checks every second whether a line
    is due, so that a line comes even while a long generation or batch runs (``heartbeat``;
    :meth:`tick` does its work, for tests with a fake ``clock``).
    """

    def __init__(
        self,
        enabled: bool = False,
        *,
        lines: Callable[[str], None] | None = None,
        interval: float | None = None,
        clock: Callable[[], float] = time.monotonic,
        heartbeat: bool = True,
    ) -> None:
        self.enabled = enabled
        self._progress: Any = None
        self._lines = None if enabled else lines
        self._interval = PLAIN_INTERVAL if interval is None else interval
        self._clock = clock
        self._heartbeat = heartbeat
        self._tasks: dict[int, _Task] = {}
        self._next = 0  # the next task's key
        self._latest: int | None = None  # the task last moved
        self._finished: _Task | None = None  # the stage's task that finished last
        self._stage: str | None = None
        self._stage_started = clock()
        self._last_line = clock()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def plain(self) -> bool:
        """Whether this is plain-line mode."""
        return self._lines is not None

    def __enter__(self) -> Progress:
        if self.enabled:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                TextColumn,
                TimeElapsedColumn,
            )
            from rich.progress import Progress as RichProgress

            self._progress = RichProgress(
                TextColumn("{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn("{task.fields[info]}"),
                TimeElapsedColumn(),
            )
            self._progress.__enter__()
        elif self.plain and self._heartbeat:
            self._stop.clear()
            self._thread = threading.Thread(target=self._beat, name="mbn-progress", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._progress is not None:
            self._progress.__exit__(*exc)
            self._progress = None
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
            self._thread = None

    def _beat(self) -> None:
        while not self._stop.wait(min(1.0, self._interval)):
            self.tick()

    def stage(self, name: str | None) -> None:
        """The stage now running (None: none); plain-line mode counts its time from here."""
        with self._lock:
            self._stage = name
            self._stage_started = self._last_line = self._clock()
            self._latest = None
            self._finished = None

    def task(self, description: str, total: int | None, *, quiet: bool = False) -> Any:
        """A new bar (None when silent); a ``quiet`` task has no plain line of its own (the run's
        bar over its stages, whose lines the runner prints)."""
        if self._progress is not None:
            return self._progress.add_task(description, total=total, info="")
        if not self.plain:
            return None
        with self._lock:
            key = self._next
            self._next += 1
            self._tasks[key] = _Task(description, total, started=self._clock(), quiet=quiet)
            if not quiet:
                self._latest = key
            return key

    def update(self, task: Any, *, completed: int | None = None, info: str = "") -> None:
        if self._progress is not None and task is not None:
            self._progress.update(task, completed=completed, info=info)
            return
        if not self.plain or task not in self._tasks:
            return
        with self._lock:
            t = self._tasks[task]
            if completed is not None:
                t.completed = completed
            t.info = info
            if t.quiet:
                return
            self._latest = task
            now = self._clock()
            if t.total is not None and t.completed >= t.total:
                # a task that ran a while says that it finished (a short one says nothing)
                if now - t.started >= self._interval:
                    self._say(t, now)
                del self._tasks[task]
                self._latest = None
                self._finished = t
                return
        self.tick()

    def tick(self) -> None:
        """Plain-line mode: print the line that is due (one per interval of a stage)."""
        if not self.plain:
            return
        with self._lock:
            now = self._clock()
            if self._stage is None or now - self._last_line < self._interval:
                return
            t = self._tasks.get(self._latest) if self._latest is not None else None
            self._say(t, now)

    def _say(self, t: _Task | None, now: float) -> None:
        """One plain line (the lock held): the stage, the task and how long the stage has run."""
        stage = f"stage {self._stage}: " if self._stage else ""
        what = "running"
        if t is not None:
            what = _state(t)
        elif self._finished is not None:
            what = f"running on after {_state(self._finished)}"
        assert self._lines is not None
        self._lines(f"{stage}{what}; {_clock(now - self._stage_started)} into the stage")
        self._last_line = now


def _state(t: _Task) -> str:
    """``RF: DE generations 120/300, best 23.41``."""
    done = f"{t.completed}/{t.total}" if t.total is not None else f"{t.completed}"
    return f"{t.description} {done}" + (f", {t.info}" if t.info else "")


def _clock(seconds: float) -> str:
    """``45 s``, ``2 min 05 s``, ``1 h 02 min``."""
    m, sec = divmod(round(seconds), 60)
    h, m = divmod(m, 60)
    return f"{h} h {m:02d} min" if h else (f"{m} min {sec:02d} s" if m else f"{sec} s")
