"""Progress of a run: rich progress bars (one per stage, one per DE), or nothing."""

from __future__ import annotations

from typing import Any

__all__ = ["Progress"]


class Progress:
    """Rich progress bars when ``enabled``, else a silent stand-in with the same methods.

    Used as a context manager; :meth:`task` adds a bar, :meth:`update` moves it, :meth:`log`
    prints a line above the bars.
    """

    def __init__(self, enabled: bool = False) -> None:
        self.enabled = enabled
        self._progress: Any = None

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
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._progress is not None:
            self._progress.__exit__(*exc)
            self._progress = None

    def task(self, description: str, total: int | None) -> Any:
        """A new bar (None when disabled)."""
        if self._progress is None:
            return None
        return self._progress.add_task(description, total=total, info="")

    def update(self, task: Any, *, completed: int | None = None, info: str = "") -> None:
        if self._progress is not None and task is not None:
            self._progress.update(task, completed=completed, info=info)
