"""A run folder: what a run writes and where, read back by later stages, the report and resumes.

Layout (every file written atomically)::

    run.json          what was asked: kind, mbn version, seed, the whole effective config
    checkpoints/      DE state after every generation (NAME.npz), for resuming
    stages/NAME.json  each finished stage's data
    records/          arrays recorded for the report (trajectories, recordings), NPZ
    controllers/      controller and multiplier files (docs/controllers.md)
    figures/          the report's pictures
    results.json      seeds, config, versions, per-stage metrics (and the experiment's extras)
    timings.json      wall-clock seconds and robot-steps per stage (kept out of results.json)
"""

from __future__ import annotations

import io
import shutil
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any, TypeVar

import numpy as np

from mbn.errors import MbnInputError
from mbn.evolution.de import DEState
from mbn.experiments.pipeline.results import Readable
from mbn.host import put
from mbn.io import atomic_open, expect_object, read_json, write_json_atomic

__all__ = ["SUBFOLDERS", "Checkpoint", "RunDir"]

D = TypeVar("D")
T = TypeVar("T")

#: The folders of a run.
SUBFOLDERS = ("checkpoints", "stages", "records", "controllers", "figures")
#: The files of a run at its top level.
FILES = ("results.json", "report.md", "report.html", "timings.json", "run.json")


@dataclass(frozen=True)
class Checkpoint:
    """A DE run after some generation: its state and the best and mean fitness of every
    generation so far (``history[g] = (best, mean)``)."""

    state: DEState
    history: list[tuple[float, float]]


@dataclass(frozen=True)
class RunDir:
    """The folder of one run (see the module docstring for its layout)."""

    root: Path

    # -- places ----------------------------------------------------------------------------------

    @property
    def manifest(self) -> Path:
        return self.root / "run.json"

    @property
    def results(self) -> Path:
        return self.root / "results.json"

    @property
    def timings(self) -> Path:
        return self.root / "timings.json"

    def stage_file(self, name: str) -> Path:
        return self.root / "stages" / f"{name}.json"

    def checkpoint_file(self, name: str) -> Path:
        return self.root / "checkpoints" / f"{name}.npz"

    def controller_file(self, name: str) -> Path:
        return self.root / "controllers" / f"{name}.json"

    def record_file(self, name: str) -> Path:
        return self.root / "records" / f"{name}.npz"

    def figure_file(self, name: str) -> Path:
        return self.root / "figures" / name

    # -- the folder ------------------------------------------------------------------------------

    def create(self) -> None:
        """Create the folder and its sub-folders (existing ones are kept)."""
        self.root.mkdir(parents=True, exist_ok=True)
        for sub in SUBFOLDERS:
            (self.root / sub).mkdir(exist_ok=True)

    def clear(self) -> None:
        """Remove what a run writes (``--force``), leaving anything else in place."""
        for name in SUBFOLDERS:
            shutil.rmtree(self.root / name, ignore_errors=True)
        for name in FILES:
            (self.root / name).unlink(missing_ok=True)

    def remove_temporary_files(self) -> list[Path]:
        """Remove the temporary files a killed run left behind (``.NAME.*.tmp``, from atomic
        writes that never finished); returns them."""
        found = [p for p in self.root.glob(".*.tmp") if p.is_file()]
        for sub in SUBFOLDERS:
            found += [p for p in (self.root / sub).glob(".*.tmp") if p.is_file()]
        for p in found:
            p.unlink(missing_ok=True)
        return found

    def read_manifest(self) -> dict[str, Any]:
        return expect_object(read_json(self.manifest), str(self.manifest))

    # -- stages ----------------------------------------------------------------------------------

    def stage_done(self, name: str) -> bool:
        return self.stage_file(name).exists()

    def read_stage(self, name: str) -> dict[str, Any]:
        """The data of a finished stage (one line naming the file when it is missing)."""
        path = self.stage_file(name)
        if not path.exists():
            raise MbnInputError(f"{path}: stage {name!r} has not run in this folder")
        data = read_json(path)
        if not isinstance(data, dict):
            raise MbnInputError(f"{path}: not a stage result")
        return data

    def read_result(self, stage: type[Readable[D]]) -> D:
        """The typed result of a finished stage, by its class (``rundir.read_result(RFStage)``:
        its record, checked; one line naming the file when it is missing or does not fit)."""
        return stage.from_json(self.read_stage(stage.name), self.stage_file(stage.name))

    def write_stage(self, name: str, data: dict[str, Any]) -> None:
        write_json_atomic(self.stage_file(name), data)

    def read_timings(self) -> dict[str, float]:
        """``timings.json``'s ``stages``: wall-clock seconds per stage (empty without the
        file)."""
        return {str(k): float(v) for k, v in self._timings_field("stages").items()}

    def read_robot_steps(self) -> dict[str, int]:
        """``timings.json``'s ``robot_steps``: the robot-steps each stage counted (empty
        without the file, or for one written before the field existed)."""
        return {str(k): int(v) for k, v in self._timings_field("robot_steps").items()}

    def _timings_field(self, name: str) -> dict[str, Any]:
        if not self.timings.exists():
            return {}
        data = read_json(self.timings)
        field = data.get(name, {}) if isinstance(data, dict) else {}
        return field if isinstance(field, dict) else {}

    def write_timings(
        self, timings: dict[str, float], robot_steps: dict[str, int] | None = None
    ) -> None:
        """``timings.json``: ``stages`` (name -> wall-clock seconds), ``robot_steps`` (name ->
        the robot-steps counted while it ran, :func:`mbn.world.rollout.robot_steps`; none
        given: ``{}``), and their sums ``total_seconds`` and ``total_robot_steps``."""
        steps = dict(robot_steps or {})
        write_json_atomic(
            self.timings,
            {
                "stages": timings,
                "robot_steps": steps,
                "total_seconds": round(sum(timings.values()), 2),
                "total_robot_steps": int(sum(steps.values())),
            },
        )

    # -- checkpoints -----------------------------------------------------------------------------

    def save_checkpoint(self, name: str, checkpoint: Checkpoint) -> None:
        state = checkpoint.state
        with atomic_open(self.checkpoint_file(name), "wb") as handle:
            np.savez(
                handle,
                population=np.asarray(state.population),
                fitness=np.asarray(state.fitness),
                best_genome=np.asarray(state.best_genome),
                best_fitness=np.asarray(state.best_fitness),
                generation=np.asarray(state.generation),
                history=np.asarray(checkpoint.history, dtype=float),
            )

    def load_checkpoint(self, name: str) -> Checkpoint:
        path = self.checkpoint_file(name)
        try:
            with np.load(path) as z:
                state = DEState(
                    population=put(z["population"]),
                    fitness=put(z["fitness"]),
                    best_genome=put(z["best_genome"]),
                    best_fitness=put(z["best_fitness"]),
                    generation=put(z["generation"]),
                )
                history = [(float(row[0]), float(row[1])) for row in z["history"]]
        except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise MbnInputError(
                f"{path}: unreadable checkpoint ({exc or type(exc).__name__})"
            ) from None
        if len(history) != int(state.generation) + 1:
            raise MbnInputError(
                f"{path}: unreadable checkpoint (generation {int(state.generation)} with "
                f"{len(history)} history rows)"
            )
        return Checkpoint(state, history)

    # -- records ---------------------------------------------------------------------------------

    def save_record(self, name: str, arrays: dict[str, Any]) -> None:
        """Arrays for the report, ``records/NAME.npz`` (compressed)."""
        buf = io.BytesIO()
        np.savez_compressed(buf, **{k: np.asarray(v) for k, v in arrays.items()})  # type: ignore[arg-type]
        with atomic_open(self.record_file(name), "wb") as handle:
            handle.write(buf.getvalue())

    def load_record(self, name: str) -> dict[str, np.ndarray]:
        path = self.record_file(name)
        try:
            with np.load(path) as z:
                return {k: z[k] for k in z.files}
        except (OSError, ValueError) as exc:
            raise MbnInputError(f"{path}: unreadable record ({exc})") from None

    def load_record_as(self, name: str, cls: Callable[..., T]) -> T:
        """The record ``name`` as ``cls`` built from its arrays by field (a ``NamedTuple`` of
        the record's fields, as the stage that saved it declares them)."""
        return cls(**self.load_record(name))

    def save_trajectories(
        self, name: str, trajectories: dict[str, Any], fields: tuple[str, ...]
    ) -> None:
        """Several trajectories in one record: ``NAME.npz`` holds ``who.field`` arrays."""
        arrays = {
            f"{who}.{f}": np.asarray(getattr(traj, f))
            for who, traj in trajectories.items()
            for f in fields
        }
        self.save_record(name, arrays)

    def load_trajectories(self, name: str) -> dict[str, SimpleNamespace]:
        """The trajectories of :meth:`save_trajectories`, ``who -> namespace of fields``."""
        out: dict[str, dict[str, np.ndarray]] = {}
        for key, value in self.load_record(name).items():
            who, f = key.split(".", 1)
            out.setdefault(who, {})[f] = value
        return {who: SimpleNamespace(**fields) for who, fields in out.items()}
