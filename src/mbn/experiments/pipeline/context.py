"""What a stage sees while it runs: its folder, settings, seeds and key, the outputs of the stages
it needs, progress bars, and DE checkpointed after every generation."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import jax
import numpy as np

from mbn.errors import MbnInputError
from mbn.evolution.de import DEConfig, DEState
from mbn.experiments.pipeline.progress import Progress
from mbn.experiments.pipeline.runconfig import RunConfig
from mbn.experiments.pipeline.rundir import Checkpoint, RunDir

__all__ = ["DEResult", "StageContext", "generation_stats"]


@dataclass(frozen=True)
class DEResult:
    """A finished DE run: the data a stage records (``data``: the best genome, its fitness, the
    generations and the best and mean fitness of every generation) and the final state."""

    data: dict[str, Any]
    state: DEState


def generation_stats(state: DEState) -> tuple[float, float]:
    """Best fitness and mean finite fitness of a population."""
    fit = np.asarray(state.fitness, dtype=float)
    return float(state.best_fitness), float(np.mean(fit[np.isfinite(fit)]))


@dataclass
class StageContext:
    """One stage's view of the run.

    Attributes:
        rundir: the run folder (the stage writes its files through it).
        config: the run's whole effective config.
        seed: the run's seed.
        seeds: the seeds derived from it (recorded in ``results.json``).
        run_key: the run's key (``jax.random.key(seed)``, made once by the runner).
        name: the name of the stage running.
        key_id: its key number.
        needs: the stages it reads.
        progress: progress bars (silent when disabled).
        log: prints a notice (one line).
        workers: threads evaluating the populations' parts
            (:func:`mbn.experiments.evolve.split_fitness`; the results do not depend on it).
    """

    rundir: RunDir
    config: RunConfig
    seed: int
    seeds: dict[str, int]
    run_key: jax.Array
    name: str
    key_id: int
    needs: tuple[str, ...]
    progress: Progress
    log: Callable[[str], None] = print
    workers: int = 1

    @property
    def key(self) -> jax.Array:
        """This stage's key: ``fold_in(run key, stage.key_id)``."""
        return jax.random.fold_in(self.run_key, self.key_id)

    @property
    def settings(self) -> Any:
        """This stage's settings (its section of the config)."""
        return self.config[self.name]

    def section(self, name: str) -> Any:
        """A section of the config (shared settings, or another stage's)."""
        return self.config[name]

    def read(self, name: str) -> dict[str, Any]:
        """The data of a stage this one needs."""
        if name not in self.needs:
            raise RuntimeError(f"stage {self.name} reads {name!r} but does not declare it")
        return self.rundir.read_stage(name)

    def _resumable(self, name: str, config: DEConfig) -> Checkpoint | None:
        """The checkpoint of DE ``name`` if there is a usable one; an unreadable or foreign one
        is reported in one line and removed (the DE then starts again from its first
        generation, which gives the same result: every generation draws from its own key)."""
        path = self.rundir.checkpoint_file(name)
        if not path.exists():
            return None
        try:
            cp = self.rundir.load_checkpoint(name)
            shape = tuple(cp.state.population.shape)
            if shape != (config.popsize, config.num_dims):
                raise MbnInputError(
                    f"{path}: a population of shape {shape}, not ({config.popsize}, "
                    f"{config.num_dims})"
                )
        except MbnInputError as exc:
            self.log(f"notice: {exc}; {name} starts again from its first generation")
            path.unlink(missing_ok=True)
            return None
        return cp

    def evolve(
        self,
        name: str,
        config: DEConfig,
        fitness: Callable[[jax.Array], jax.Array],
        key: jax.Array,
        generations: int,
        description: str,
        population: np.ndarray | None = None,
    ) -> DEResult:
        """DE for ``generations`` generations, checkpointed after each one in
        ``checkpoints/NAME.npz``; resumes from that file when it exists. Generation 0 is drawn
        at random unless ``population`` is given; generation ``g`` draws from
        ``fold_in(key, g)``. Populations are evaluated in
        :data:`~mbn.experiments.evolve.FITNESS_PARTS` parts, ``workers`` of them at once."""
        from mbn.experiments.evolve import FITNESS_PARTS, generation, split_fitness, start

        threads = max(1, min(self.workers, FITNESS_PARTS))
        with ThreadPoolExecutor(threads, thread_name_prefix="mbn-fitness") as pool:
            fitness = split_fitness(fitness, self.workers, pool)
            cp = self._resumable(name, config)
            if cp is not None:
                state, history = cp.state, list(cp.history)
            else:
                state = start(key, config, fitness, population)
                history = [generation_stats(state)]
                self.rundir.save_checkpoint(name, Checkpoint(state, history))
            g0 = int(state.generation)
            bar = self.progress.task(description, generations)
            self.progress.update(bar, completed=g0, info=f"best {history[-1][0]:.2f}")
            for g in range(g0 + 1, generations + 1):
                state = generation(key, g, state, config, fitness)
                history.append(generation_stats(state))
                self.rundir.save_checkpoint(name, Checkpoint(state, history))
                self.progress.update(bar, completed=g, info=f"best {history[-1][0]:.2f}")
            h = np.asarray(history, dtype=float)
            data = {
                "best_genome": np.asarray(state.best_genome, dtype=float).tolist(),
                "best_fitness": float(state.best_fitness),
                "generations": generations,
                "history": {"best": h[:, 0].tolist(), "mean": h[:, 1].tolist()},
            }
            return DEResult(data, state)
