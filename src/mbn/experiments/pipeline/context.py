"""What a stage sees while it runs: its folder, settings, seeds and key, the outputs of the stages
it needs, progress bars, and DE checkpointed after every generation."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar, overload

import jax
import jax.numpy as jnp
import numpy as np

from mbn.config import Settings
from mbn.errors import MbnInputError
from mbn.evolution.de import DEConfig, DEState
from mbn.experiments.pipeline.progress import Progress
from mbn.experiments.pipeline.results import Readable
from mbn.experiments.pipeline.runconfig import RunConfig
from mbn.experiments.pipeline.rundir import Checkpoint, RunDir
from mbn.host import put

__all__ = ["DEResult", "DERun", "MissingSectionError", "Seeds", "StageContext", "generation_stats"]

S = TypeVar("S", bound=Settings)
D = TypeVar("D")


@dataclass(frozen=True)
class DEResult:
    """A finished DE run: the data a stage records (``data``: the best genome, its fitness, the
    generations and the best and mean fitness of every generation) and the final state."""

    data: dict[str, Any]
    state: DEState


@dataclass(frozen=True)
class DERun:
    """One DE run of a group (:meth:`StageContext.evolve_group`): its checkpoint name, settings,
    key and, optionally, its generation 0."""

    name: str
    config: DEConfig
    key: jax.Array
    population: np.ndarray | None = None


def _result(state: DEState, history: list[tuple[float, float]], generations: int) -> DEResult:
    h = np.asarray(history, dtype=float)
    data = {
        "best_genome": np.asarray(state.best_genome, dtype=float).tolist(),
        "best_fitness": float(state.best_fitness),
        "generations": generations,
        "history": {"best": h[:, 0].tolist(), "mean": h[:, 1].tolist()},
    }
    return DEResult(data, state)


class MissingSectionError(MbnInputError, KeyError):
    """A stage read a section of settings its experiment does not have (a ``KeyError`` too:
    a stage that reads a section only when it is there catches that)."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


class Seeds(dict[str, int]):
    """The seeds derived from the run's seed (``Experiment.seeds``): a seed the experiment does
    not make is refused in one line naming the stage and what to give the experiment."""

    def __init__(self, seeds: dict[str, int], stage: str) -> None:
        super().__init__(seeds)
        self.stage = stage

    def __missing__(self, key: str) -> int:
        raise MbnInputError(
            f"stage {self.stage} reads the derived seed {key!r}, which its experiment does not "
            f"make (it makes {', '.join(self) or 'none'}): give the experiment "
            "seeds=derived_seeds (mbn.experiments.stages.settings), as the experiments "
            "composed of the stage library do"
        )


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

    def __post_init__(self) -> None:
        if not isinstance(self.seeds, Seeds):
            self.seeds = Seeds(self.seeds, self.name)

    @property
    def key(self) -> jax.Array:
        """This stage's key: ``fold_in(run key, stage.key_id)``."""
        return jax.random.fold_in(self.run_key, self.key_id)

    @property
    def settings(self) -> Any:
        """This stage's settings (its section of the config)."""
        return self.config[self.name]

    def section(self, cls: type[S]) -> S:
        """A section of the config (shared settings, or another stage's) by its settings class:
        ``ctx.section(DESettings)`` is the run's ``[de]``, typed."""
        try:
            return self.config.get(cls)
        except KeyError:
            raise MissingSectionError(
                f"stage {self.name} reads the settings [{cls.section}] ({cls.__name__}), which "
                "its experiment does not have: add the class to the experiment's shared "
                "settings (Experiment(shared=...))"
            ) from None

    @overload
    def read(self, stage: str) -> dict[str, Any]: ...

    @overload
    def read(self, stage: type[Readable[D]]) -> D: ...

    def read(self, stage: str | type[Readable[Any]]) -> Any:
        """The data of a stage this one needs: by its class, typed (``ctx.read(RFStage)``, its
        :attr:`~mbn.experiments.pipeline.registry.Stage.result` record); by its name, the JSON
        object of ``stages/NAME.json``."""
        name = stage if isinstance(stage, str) else stage.name
        if name not in self.needs:
            raise RuntimeError(f"stage {self.name} reads {name!r} but does not declare it")
        if isinstance(stage, str):
            return self.rundir.read_stage(name)
        return self.rundir.read_result(stage)

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
        :data:`~mbn.experiments.evolve.FITNESS_PARTS` parts, ``workers`` of them at once. A
        group of one run (:meth:`evolve_group`)."""
        from mbn.experiments.evolve import OwnedFitness, Redrawn

        run = DERun(name, config, key, population)
        # a fitness of owners is the group's as it is (every genome's owner is 0): a batched
        # sweep can merge it with the other seeds'; so is one redrawn (of such fitnesses)
        group: Any = fitness
        if not isinstance(fitness, OwnedFitness | Redrawn):
            group = lambda pop, _owner: fitness(pop)  # noqa: E731
        return self.evolve_group([run], group, generations, description)[0]

    def evolve_group(
        self,
        runs: Sequence[DERun],
        fitness: Callable[[jax.Array, jax.Array], jax.Array],
        generations: int,
        description: str,
    ) -> list[DEResult]:
        """Independent DE runs of one population size and genome length advanced side by side:
        each generation, every run's trials are evaluated in one batch, ``fitness(population,
        owner)`` (``owner[i]``: the run genome ``i`` belongs to), cut into
        :data:`~mbn.experiments.evolve.FITNESS_PARTS` parts as :meth:`evolve` does. Run ``r``
        is what :meth:`evolve` would make of it with a fitness giving each genome the values
        it gets here (its own checkpoint ``checkpoints/NAME.npz``, its generation ``g`` from
        ``fold_in(key, g)``). Few large batches cost less per robot-step than many small ones
        (``docs/speed.md``). The batch always holds every run, in order (a run already past a
        generation, after a resume, stands in with its population and its values are
        dropped), so its shape, and with it every float, is that of an uninterrupted run."""
        from mbn.evolution.de import ask, from_population, init, initialize_fitness, tell
        from mbn.experiments import batching
        from mbn.experiments.evolve import (
            FITNESS_PARTS,
            OwnedFitness,
            Redrawn,
            fitness_pool,
            join_rows,
            split_fitness,
            split_rows,
        )

        if not runs:
            return []
        configs = {(r.config.popsize, r.config.num_dims) for r in runs}
        if len(configs) != 1:
            raise MbnInputError(f"a DE group needs one population shape, got {sorted(configs)}")
        ((popsize, _),) = configs
        owner = put(np.repeat(np.arange(len(runs)), popsize))
        bounds = tuple(r * popsize for r in range(len(runs) + 1))

        def drawn(run: DERun) -> DEState:  # generation 0 before its fitness
            if run.population is None:
                return init(jax.random.fold_in(run.key, 0), run.config)
            return from_population(jnp.asarray(run.population), run.config)

        threads = max(1, min(self.workers, FITNESS_PARTS))
        # a fitness whose episodes are redrawn every N generations gives generation g's
        redrawn = fitness if isinstance(fitness, Redrawn) else None
        first = redrawn.at(0) if redrawn is not None else fitness
        batcher = batching.current() if isinstance(first, OwnedFitness) else None
        with contextlib.ExitStack() as stack:
            pool = stack.enter_context(fitness_pool(threads))
            parted: dict[int, Callable[[jax.Array, jax.Array], jax.Array]] = {}
            # a batched sweep's other seeds wait for this group's populations while it evolves
            if batcher is not None:
                stack.enter_context(batcher.evolving())

            def evaluate(populations: list[jax.Array], g: int = 0) -> list[jax.Array]:
                """The values of every run's population under generation ``g``'s fitness."""
                now = redrawn.at(g) if redrawn is not None else fitness
                joined = populations[0] if len(populations) == 1 else join_rows(tuple(populations))
                if batcher is not None:  # merged with the other seeds of a batched sweep
                    assert isinstance(now, OwnedFitness)
                    values = put(batcher.evaluate(now, joined, owner))
                else:
                    draw = redrawn.draw(g) if redrawn is not None else 0
                    if draw not in parted:
                        parted.clear()  # one draw at a time
                        parted[draw] = split_fitness(now, self.workers, pool)
                    values = parted[draw](joined, owner)
                if len(populations) == 1:  # one run: nothing to cut
                    return [values]
                return list(split_rows(values, bounds))

            checkpoints = [self._resumable(run.name, run.config) for run in runs]
            states = [
                drawn(run) if cp is None else cp.state
                for run, cp in zip(runs, checkpoints, strict=True)
            ]
            histories = [[] if cp is None else list(cp.history) for cp in checkpoints]
            fresh = [i for i, cp in enumerate(checkpoints) if cp is None]
            if fresh:
                values = evaluate([st.population for st in states])
                for i in fresh:
                    states[i] = initialize_fitness(states[i], values[i], runs[i].config)
                    histories[i] = [generation_stats(states[i])]
                    self.rundir.save_checkpoint(runs[i].name, Checkpoint(states[i], histories[i]))
            g0 = min(int(st.generation) for st in states)
            bar = self.progress.task(description, generations)
            best = max(h[-1][0] for h in histories)
            self.progress.update(bar, completed=g0, info=f"best {best:.2f}")
            for g in range(g0 + 1, generations + 1):
                behind = [i for i, st in enumerate(states) if int(st.generation) < g]
                if redrawn is not None and redrawn.draw(g) != redrawn.draw(g - 1):
                    # new episodes: the populations are judged on them before any trial is
                    # (their best too), so that a trial meets its parent on the same episodes
                    values = evaluate([st.population for st in states], g)
                    for i in behind:
                        states[i] = initialize_fitness(states[i], values[i], runs[i].config)
                trials = [st.population for st in states]
                for i in behind:
                    trials[i] = ask(jax.random.fold_in(runs[i].key, g), states[i], runs[i].config)
                values = evaluate(trials, g)
                for i in behind:
                    states[i] = tell(states[i], trials[i], values[i], runs[i].config)
                    histories[i].append(generation_stats(states[i]))
                    self.rundir.save_checkpoint(runs[i].name, Checkpoint(states[i], histories[i]))
                best = max(h[-1][0] for h in histories)
                self.progress.update(bar, completed=g, info=f"best {best:.2f}")
            return [_result(st, h, generations) for st, h in zip(states, histories, strict=True)]
