"""``mbn reproduce``: the paper's whole experiment, stage by stage, checkpointed and resumable.

Stages (paper section 3; ``docs/reproduce.md`` describes each and every deviation):

1. ``multiplier``: the shipped multiplier (6 neurons by default) or one trained again.
2. ``rf``: the right-follower, 12 genes evolved by DE/best/1/bin on the crossroads.
3. ``lf_search``: which 3 connections of RF to re-evolve for the left-follower: every triple of
   connections into the turning neuron is evolved briefly and the best is kept.
4. ``lf``: those 3 connections re-evolved at length.
5. ``im``: the interpreter of RF with the connections that differ between RF and LF programmable,
   and the RF and LF programs.
6. ``pm``: the program module, evolved with the interpreter fixed (the paper's product reward).
7. ``tests``: the paper's protocol, 200 jittered starts and the held-out maze, for RF, LF, the
   interpreter with each program, the MBN and the published weights.

A run lives in one folder: ``run.json`` (what was asked), ``checkpoints/`` (every DE generation),
``stages/`` (each finished stage's results), ``controllers/``, ``figures/``, ``results.json``,
``report.md``, ``report.html`` and ``timings.json`` (wall-clock times are kept out of
``results.json``, which depends only on the seed and the settings). Every file is written
atomically, so an interrupted run (even ``kill -9``) resumes from its last generation and ends
with the same ``results.json`` as an uninterrupted one.

Seeds: the run's seed becomes one JAX key here; stage ``s`` draws from ``fold_in(key, s)`` and
generation ``g`` of a DE from ``fold_in(stage key, g)``. The jitter of the training starts and of
the test starts (NumPy, at that edge) take seeds derived from it, recorded in ``results.json``.
"""

from __future__ import annotations

import dataclasses
import io
import itertools
import json
import platform
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from mbn import __version__
from mbn.errors import MbnInputError
from mbn.evolution.de import DEConfig, DEState
from mbn.io import atomic_open, read_json, write_json_atomic

__all__ = [
    "RUN_KIND",
    "STAGES",
    "TEST_NAMES",
    "ReproduceSettings",
    "Reproduction",
    "check_out_dir",
]

RUN_KIND = "mbn.reproduce"
STAGES: tuple[str, ...] = ("multiplier", "rf", "lf_search", "lf", "im", "pm", "tests")
#: Stage numbers in the key derivation (fixed: adding a stage must not change the others' keys).
_STAGE_KEYS = {"multiplier": 1, "rf": 2, "lf_search": 3, "lf": 4, "im": 5, "pm": 6, "tests": 7}
CONTROLLERS = ("rf", "lf", "im", "mbn", "multiplier")
#: Controllers tested and the rule each is judged by.
TESTED: tuple[tuple[str, str], ...] = (
    ("rf", "right"),
    ("lf", "left"),
    ("im_rf", "right"),
    ("im_lf", "left"),
    ("mbn", "tiles"),
    ("published_rf", "right"),
    ("published_lf", "left"),
)
TEST_NAMES: tuple[str, ...] = tuple(
    f"{name}{suffix}" for name, _ in TESTED for suffix in ("", "_jitter", "_heldout")
)
#: The paper's (1-based) names of the connections into the turning neuron (neuron 2).
_TURNING_CANDIDATES = ("W[1,0]", "W[1,1]", "W[1,2]", "WE[1,0]", "WE[1,1]", "WE[1,2]")


@dataclass(frozen=True)
class ReproduceSettings:
    """Everything a run depends on besides its seed (all recorded in ``run.json``).

    ``quick()`` is a smoke run of every stage and every output with tiny budgets; ``full()`` the
    real one (``docs/reproduce.md`` gives the reasons for each number).
    """

    quick: bool = False
    multiplier_neurons: int = 6
    retrain_multiplier: bool = False
    weight_bound: float = 20.0
    noise_sigma: float = 0.3
    noise_copies: int = 3
    rf_generations: int = 300
    rf_variants: int = 4
    rf_restarts: int = 2
    lf_candidates: tuple[str, ...] = _TURNING_CANDIDATES
    lf_search_generations: int = 100
    lf_search_variants: int = 2
    lf_generations: int = 200
    lf_variants: int = 4
    lf_approaches: tuple[str, ...] = ("south", "west", "east")
    pm_generations: int = 250
    pm_variants: int = 1
    pm_bound: float = 10.0
    pm_init: float = 10.0
    pm_noise_sigma: float = 1.0
    pm_noise_copies: int = 0
    pm_approaches: tuple[str, ...] = ("south", "west", "east")
    pm_reward: str = "memory"
    pm_fidelity: float = 2.0
    camera_range: float = 0.8
    episode_seconds: float = 30.0
    test_seconds: float = 90.0
    mbn_seconds: float = 120.0
    jitter_per_mark: int = 20
    heldout_repeats: int = 17
    test_maze: str = "fig4"
    heldout_maze: str = "heldout"
    popsize: int = 18

    @classmethod
    def full(cls, *, retrain_multiplier: bool = False) -> ReproduceSettings:
        return cls(retrain_multiplier=retrain_multiplier)

    @classmethod
    def quick_run(cls, *, retrain_multiplier: bool = False) -> ReproduceSettings:
        return cls(
            quick=True,
            retrain_multiplier=retrain_multiplier,
            noise_copies=1,
            rf_generations=15,
            rf_variants=1,
            rf_restarts=2,
            lf_search_generations=2,
            lf_search_variants=1,
            lf_generations=20,
            lf_variants=1,
            pm_generations=3,
            pm_variants=1,
            jitter_per_mark=2,
            heldout_repeats=2,
        )

    def __post_init__(self) -> None:
        if self.pm_reward not in ("paper", "memory"):
            raise MbnInputError(f"pm_reward must be paper or memory, got {self.pm_reward!r}")
        if self.noise_copies < 0 or not self.noise_sigma >= 0:
            raise MbnInputError("noise_copies and noise_sigma must be >= 0")
        if self.pm_noise_copies < 0 or not self.pm_noise_sigma >= 0:
            raise MbnInputError("pm_noise_copies and pm_noise_sigma must be >= 0")
        if not 0 < self.pm_init <= self.pm_bound:
            raise MbnInputError("pm_init must be in (0, pm_bound]")
        if self.rf_restarts < 1:
            raise MbnInputError(f"rf_restarts must be >= 1, got {self.rf_restarts}")
        if not self.pm_fidelity >= 0:
            raise MbnInputError(f"pm_fidelity must be >= 0, got {self.pm_fidelity}")

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["lf_candidates"] = list(self.lf_candidates)
        d["lf_approaches"] = list(self.lf_approaches)
        d["pm_approaches"] = list(self.pm_approaches)
        return d


def versions() -> dict[str, str]:
    """Versions of what the results depend on."""
    import jaxlib
    import matplotlib
    import optax

    return {
        "mbn": __version__,
        "python": platform.python_version(),
        "jax": jax.__version__,
        "jaxlib": jaxlib.__version__,
        "numpy": np.__version__,
        "optax": optax.__version__,
        "matplotlib": matplotlib.__version__,
        "platform": jax.default_backend(),
    }


def check_out_dir(out: Path, *, resume: bool, force: bool) -> None:
    """Refuse an output folder that holds something else (one clear line).

    A folder holding another run (``run.json``) is used only with ``resume`` (continue it) or
    ``force`` (start anew); a folder holding other files is never used; a file is refused.
    """
    if resume and force:
        raise MbnInputError("--resume and --force exclude each other")
    if out.exists() and not out.is_dir():
        raise MbnInputError(f"--out {out}: is a file, not a folder")
    if not out.exists():
        if resume:
            raise MbnInputError(f"--out {out}: nothing to resume (the folder does not exist)")
        return
    entries = [p for p in out.iterdir()]
    if not entries:
        if resume:
            raise MbnInputError(f"--out {out}: nothing to resume (the folder is empty)")
        return
    manifest = out / "run.json"
    if not manifest.exists():
        raise MbnInputError(
            f"--out {out}: the folder holds other files and no run (run.json); choose an empty "
            "or new folder"
        )
    data = read_json(manifest)
    if not isinstance(data, dict) or data.get("kind") != RUN_KIND:
        raise MbnInputError(f"{manifest}: not a reproduce run (kind {data.get('kind')!r})")
    if not (resume or force):
        raise MbnInputError(
            f"--out {out} holds another run (seed {data.get('seed')}); pass --resume to continue "
            "it or --force to start anew"
        )


def _clear_run(out: Path) -> None:
    """Remove what a run writes (``--force``), leaving anything else in place."""
    for name in ("checkpoints", "stages", "controllers", "figures"):
        shutil.rmtree(out / name, ignore_errors=True)
    for name in ("results.json", "report.md", "report.html", "timings.json", "run.json"):
        (out / name).unlink(missing_ok=True)


# ---------------------------------------------------------------------------------------------
# Progress
# ---------------------------------------------------------------------------------------------


class _Progress:
    """Rich progress bars (one per stage, one per DE), or nothing."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self._progress: Any = None

    def __enter__(self) -> _Progress:
        if self.enabled:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
            )

            self._progress = Progress(
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

    def task(self, description: str, total: int | None) -> Any:
        if self._progress is None:
            return None
        return self._progress.add_task(description, total=total, info="")

    def update(self, task: Any, *, completed: int | None = None, info: str = "") -> None:
        if self._progress is not None and task is not None:
            self._progress.update(task, completed=completed, info=info)

    def log(self, message: str) -> None:
        if self._progress is not None:
            self._progress.console.print(message)


# ---------------------------------------------------------------------------------------------
# The run
# ---------------------------------------------------------------------------------------------


@dataclass
class Reproduction:
    """One run of the whole experiment in folder ``out``.

    ``run()`` does every stage not yet done (a stage's results are in ``stages/NAME.json`` once it
    is done), then writes ``results.json`` and the report.
    """

    out: Path
    seed: int
    settings: ReproduceSettings
    progress: bool = False
    log: Callable[[str], None] = print
    _bars: _Progress = field(init=False, repr=False)
    _timings: dict[str, float] = field(init=False, default_factory=dict)

    def __post_init__(self) -> None:
        self.out = Path(self.out)
        self.key = jax.random.key(self.seed)
        self.seeds = {
            "seed": self.seed,
            "crossroad_jitter": self.seed,
            "test_jitter": self.seed + 1,
            "heldout_jitter": self.seed + 2,
            "pm_crossroad_jitter": self.seed + 3,
        }

    # -- folder -------------------------------------------------------------------------------

    def _manifest(self) -> dict[str, Any]:
        return {
            "kind": RUN_KIND,
            "mbn_version": __version__,
            "seed": self.seed,
            "settings": self.settings.to_dict(),
        }

    def prepare(self, *, resume: bool, force: bool) -> None:
        """Check the folder (:func:`check_out_dir`), then create it or check what it holds."""
        check_out_dir(self.out, resume=resume, force=force)
        if force:
            _clear_run(self.out)
        self.out.mkdir(parents=True, exist_ok=True)
        manifest = self.out / "run.json"
        if resume and manifest.exists():
            old = read_json(manifest)
            mine = self._manifest()
            for k in ("seed", "settings"):
                if old.get(k) != mine[k]:
                    what = "seed" if k == "seed" else "settings (--quick, --retrain)"
                    raise MbnInputError(
                        f"{manifest}: the run was started with other {what}: "
                        f"{json.dumps(old.get(k))[:120]}; resume it with the same options"
                    )
        else:
            write_json_atomic(manifest, self._manifest())
        for sub in ("checkpoints", "stages", "controllers", "figures"):
            (self.out / sub).mkdir(exist_ok=True)
        timings = self.out / "timings.json"
        if timings.exists():
            self._timings = dict(read_json(timings).get("stages", {}))

    def stage_key(self, name: str) -> jax.Array:
        return jax.random.fold_in(self.key, _STAGE_KEYS[name])

    def _stage_path(self, name: str) -> Path:
        return self.out / "stages" / f"{name}.json"

    def stage_done(self, name: str) -> bool:
        return self._stage_path(name).exists()

    def stage(self, name: str) -> dict[str, Any]:
        data = read_json(self._stage_path(name))
        if not isinstance(data, dict):
            raise MbnInputError(f"{self._stage_path(name)}: not a stage result")
        return data

    def _finish_stage(self, name: str, data: dict[str, Any], seconds: float) -> None:
        write_json_atomic(self._stage_path(name), data)
        self._timings[name] = round(seconds, 2)
        self._write_timings()

    def _write_timings(self) -> None:
        write_json_atomic(
            self.out / "timings.json",
            {"stages": self._timings, "total_seconds": round(sum(self._timings.values()), 2)},
        )

    # -- DE with a checkpoint per generation -------------------------------------------------

    def evolve(
        self,
        name: str,
        config: DEConfig,
        fitness: Callable[[jax.Array], jax.Array],
        key: jax.Array,
        generations: int,
        description: str,
        population: np.ndarray | None = None,
    ) -> tuple[dict[str, Any], DEState]:
        """DE for ``generations`` generations, checkpointed after each one in
        ``checkpoints/NAME.npz``; resumes from that file when it exists. Generation 0 is drawn
        at random unless ``population`` is given. Returns the stage data (the best genome, its
        fitness, and the best and mean fitness of every generation) and the final state."""
        from mbn.experiments.evolve import generation, start

        path = self.out / "checkpoints" / f"{name}.npz"
        if path.exists():
            state, history = _load_checkpoint(path)
        else:
            state = start(key, config, fitness, population)
            history = [_gen_stats(state)]
            _save_checkpoint(path, state, history)
        g0 = int(state.generation)
        bar = self._bars.task(description, generations)
        self._bars.update(bar, completed=g0, info=f"best {history[-1][0]:.2f}")
        for g in range(g0 + 1, generations + 1):
            state = generation(key, g, state, config, fitness)
            history.append(_gen_stats(state))
            _save_checkpoint(path, state, history)
            self._bars.update(bar, completed=g, info=f"best {history[-1][0]:.2f}")
        h = np.asarray(history, dtype=float)
        data = {
            "best_genome": np.asarray(state.best_genome, dtype=float).tolist(),
            "best_fitness": float(state.best_fitness),
            "generations": generations,
            "history": {"best": h[:, 0].tolist(), "mean": h[:, 1].tolist()},
        }
        return data, state

    # -- stages -------------------------------------------------------------------------------

    def run(self) -> dict[str, Any]:
        """Every stage not yet done, then ``results.json`` and the report; returns the results."""
        runners: dict[str, Callable[[], dict[str, Any]]] = {
            "multiplier": self._multiplier,
            "rf": self._rf,
            "lf_search": self._lf_search,
            "lf": self._lf,
            "im": self._im,
            "pm": self._pm,
            "tests": self._tests,
        }
        with _Progress(self.progress) as bars:
            self._bars = bars
            overall = bars.task("mbn reproduce", len(STAGES) + 1)
            for k, name in enumerate(STAGES):
                bars.update(overall, completed=k, info=name)
                if self.stage_done(name):
                    self.log(f"stage {name}: done before, kept")
                    continue
                t0 = time.perf_counter()
                data = runners[name]()
                self._finish_stage(name, data, time.perf_counter() - t0)
                self.log(f"stage {name}: {_stage_line(name, data)}")
            bars.update(overall, completed=len(STAGES), info="report")
            t0 = time.perf_counter()
            results = self.results()
            write_json_atomic(self.out / "results.json", results)
            from mbn.experiments.report import write_report

            write_report(self, results)
            self._timings["report"] = round(time.perf_counter() - t0, 2)
            self._write_timings()
            bars.update(overall, completed=len(STAGES) + 1, info="done")
        return results

    def _multiplier(self) -> dict[str, Any]:
        from mbn.networks.multiplier import (
            evaluate,
            load_default,
            save_multiplier,
            shipped_metrics,
            validation_pairs,
        )
        from mbn.networks.multiplier_train import recipe, train_stages

        n = self.settings.multiplier_neurons
        key = self.stage_key("multiplier")
        if self.settings.retrain_multiplier:
            bar = self._bars.task(f"training the {n}-neuron multiplier", None)

            def report(done: int, total: int) -> None:
                self._bars.update(bar, completed=done, info="")

            mul, metrics = train_stages(key, recipe(n), progress=report)
            metrics["training"]["seed"] = self.seed
            source = "trained by this run"
        else:
            mul = load_default(n)
            metrics = shipped_metrics(n)
            source = f"shipped (multiplier_{n}.json)"
        measured = evaluate(mul, validation_pairs(jax.random.fold_in(key, 1), 100))
        save_multiplier(self.out / "controllers" / "multiplier.json", mul, metrics)
        return {
            "source": source,
            "neurons": n,
            "tau_ratio": 0.1,
            "metrics": measured,
        }

    def _multiplier_model(self) -> Any:
        from mbn.networks.multiplier import load_multiplier

        return load_multiplier(self.out / "controllers" / "multiplier.json")

    def _de_config(self, dims: int, bound: float, init: float | None = None) -> DEConfig:
        init = bound if init is None else init
        return DEConfig(
            num_dims=dims,
            popsize=self.settings.popsize,
            F=0.85,
            CR=0.2,
            maximize=True,
            lower=-bound,
            upper=bound,
            init_low=-init,
            init_high=init,
        )

    def _task(self, rule: str, variants: int, approaches: tuple[str, ...] = ("south",)) -> Any:
        from mbn.experiments.crossroads import CrossroadTask

        return CrossroadTask(
            rule=rule,
            variants=variants,
            seconds=self.settings.episode_seconds,
            seed=self.seeds["crossroad_jitter"],
            approaches=approaches,
        )

    def _score(
        self, net: Any, rule: str, variants: int, approaches: tuple[str, ...] = ("south",)
    ) -> dict[str, Any]:
        """Branch fitness and the paper's F_M, F_R, F_L of a network on the crossroads."""
        from mbn.experiments.crossroads import episode_fitness, paper_terms
        from mbn.experiments.evolve import evaluate_networks

        task = self._task(rule, variants, approaches)
        arrays = task.arrays()
        stats = evaluate_networks(
            jnp.asarray(net.W)[None], jnp.asarray(net.WE)[None], _tau(net), arrays, task
        )
        terms = paper_terms(stats)
        return {
            "branch_fitness": float(jnp.sum(episode_fitness(stats, arrays, task))),
            "episodes": arrays.episodes,
            "paper_F_M": float(jnp.sum(terms["F_M"])),
            "paper_F_R": float(jnp.sum(terms["F_R"])),
            "paper_F_L": float(jnp.sum(terms["F_L"])),
        }

    def _save_ctrnn(self, name: str, net: Any, behavior: str, metadata: dict[str, Any]) -> None:
        from mbn.controllers import CTRNNControllerSpec, save_controller

        save_controller(
            self.out / "controllers" / f"{name}.json",
            CTRNNControllerSpec(net=net, behavior=behavior, metadata=metadata),
        )

    def _noise(
        self, name: str, size: int, copies: int | None = None, sigma: float | None = None
    ) -> jax.Array:
        """The fixed weight perturbations of stage ``name`` (its key folded with 10**6, which no
        generation index reaches); ``copies`` and ``sigma`` default to the followers'."""
        from mbn.experiments.evolve import perturbations

        s = self.settings
        key = jax.random.fold_in(self.stage_key(name), 10**6)
        copies = s.noise_copies if copies is None else copies
        sigma = s.noise_sigma if sigma is None else sigma
        return perturbations(key, copies, size, sigma)

    def _evolve_follower(
        self,
        name: str,
        genome: Any,
        rule: str,
        variants: int,
        generations: int,
        population: np.ndarray | None = None,
        approaches: tuple[str, ...] = ("south",),
        restarts: int = 1,
    ) -> dict[str, Any]:
        """Evolve ``genome`` for ``rule`` on the crossroads (fitness averaged over the genome and
        its perturbed copies), ``restarts`` times from independent random populations (restart 0
        with the stage's key, checkpoint ``NAME``; restart r with the key folded with r,
        checkpoint ``NAME_restartR``), keep the restart with the best fitness, score its best
        (branch fitness and the paper's terms) and save it as ``controllers/NAME.json``."""
        from mbn.experiments.evolve import crossroad_fitness, robust_fitness

        fitness = robust_fitness(
            crossroad_fitness(genome, self._task(rule, variants, approaches)),
            self._noise(name, genome.size),
        )
        runs = []
        key = self.stage_key(name)
        for r in range(restarts):
            de, _ = self.evolve(
                name if r == 0 else f"{name}_restart{r}",
                self._de_config(genome.size, self.settings.weight_bound),
                fitness,
                key if r == 0 else jax.random.fold_in(key, r),
                generations,
                f"{name.upper()}: DE generations"
                + (f" (restart {r + 1}/{restarts})" if restarts > 1 else ""),
                population,
            )
            runs.append(de)
        chosen = max(range(restarts), key=lambda r: (runs[r]["best_fitness"], -r))
        de = dict(runs[chosen])
        if restarts > 1:
            de["restarts"] = [
                {"best_fitness": d["best_fitness"], "history": d["history"]} for d in runs
            ]
            de["chosen_restart"] = chosen
        net = genome.network(jnp.asarray(de["best_genome"]))
        score = self._score(net, rule, variants, approaches)
        connections = [str(c) for c in genome.connections]
        self._save_ctrnn(
            name,
            net,
            rule,
            {
                "made_by": "mbn reproduce",
                "stage": name,
                "seed": self.seed,
                "evolved": connections,
                **score,
            },
        )
        noise = {"copies": self.settings.noise_copies, "sigma": self.settings.noise_sigma}
        return {
            **de,
            "connections": connections,
            "noise": noise,
            "approaches": list(approaches),
            **score,
        }

    def _rf(self) -> dict[str, Any]:
        from mbn.experiments.evolve import Genome

        s = self.settings
        return self._evolve_follower(
            "rf", Genome(), "right", s.rf_variants, s.rf_generations, restarts=s.rf_restarts
        )

    def _net(self, name: str) -> Any:
        """The CTRNN of ``controllers/NAME.json`` (``rf`` or ``lf``)."""
        from mbn.controllers import read_controller_spec

        return read_controller_spec(self.out / "controllers" / f"{name}.json").net  # type: ignore[union-attr]

    def _rf_net(self) -> Any:
        return self._net("rf")

    def _lf_net(self) -> Any:
        return self._net("lf")

    def _lf_search(self) -> dict[str, Any]:
        from mbn.experiments.evolve import connection_search_fitness, robust_fitness
        from mbn.networks.programmable import Connection

        s = self.settings
        rf = self._rf_net()
        task = self._task("left", s.lf_search_variants)
        search = connection_search_fitness(rf, task)
        cands = [Connection.parse(c) for c in s.lf_candidates]
        triples = list(itertools.combinations(cands, 3))
        if not triples:
            raise MbnInputError("lf_candidates: need at least 3 connections")
        key = self.stage_key("lf_search")
        noise = self._noise("lf_search", 3)
        # Choosing: the crossroads entered round a corner too, as in a maze.
        choose = connection_search_fitness(
            rf, self._task("left", s.lf_search_variants, s.lf_approaches)
        )
        rows = []
        for t, trip in enumerate(triples):
            name = f"lf_search_{t:02d}"
            de, final = self.evolve(
                name,
                self._de_config(3, s.weight_bound),
                _bind(search, trip),
                jax.random.fold_in(key, t),
                s.lf_search_generations,
                f"LF search {t + 1}/{len(triples)}: {', '.join(map(str, trip))}",
            )
            # The final population scored with perturbed copies too: an LF that keeps its
            # behaviour when its weights move is one the interpreter can emulate.
            robust = np.asarray(robust_fitness(_bind(choose, trip), noise)(final.population))
            i = int(np.argmax(robust))
            rows.append(
                {
                    "connections": [str(c) for c in trip],
                    "best_fitness": de["best_fitness"],
                    "best_genome": de["best_genome"],
                    "robust_fitness": float(robust[i]),
                    "robust_genome": np.asarray(final.population[i], dtype=float).tolist(),
                }
            )
        best = max(range(len(rows)), key=lambda i: (rows[i]["robust_fitness"], -i))
        return {
            "triples": rows,
            "chosen": rows[best]["connections"],
            "chosen_index": best,
            "chosen_paper_notation": [_paper_name(c) for c in rows[best]["connections"]],
            "generations": s.lf_search_generations,
            "episodes": task.variants * 7,
            "noise": {"copies": s.noise_copies, "sigma": s.noise_sigma},
            "choice_approaches": list(s.lf_approaches),
        }

    def _lf(self) -> dict[str, Any]:
        from mbn.experiments.evolve import Genome
        from mbn.networks.programmable import Connection

        s = self.settings
        search = self.stage("lf_search")
        conns = tuple(Connection.parse(c) for c in search["chosen"])
        genome = Genome.around(self._rf_net(), conns)
        # Warm start: the chosen triple's final search population.
        start, _ = _load_checkpoint(
            self.out / "checkpoints" / f"lf_search_{search['chosen_index']:02d}.npz"
        )
        data = self._evolve_follower(
            "lf",
            genome,
            "left",
            s.lf_variants,
            s.lf_generations,
            np.asarray(start.population),
            s.lf_approaches,
        )
        data["connections_paper_notation"] = [_paper_name(str(c)) for c in conns]
        return data

    def _im(self) -> dict[str, Any]:
        from mbn.controllers import (
            InterpreterControllerSpec,
            save_controller,
        )
        from mbn.networks.programmable import build_interpreter, differing_connections

        rf, lf = self._rf_net(), self._lf_net()
        programmable = differing_connections(rf, lf, margin=0.0)
        interp = build_interpreter(rf, programmable, self._multiplier_model())
        programs = {
            "right": np.asarray(interp.program_of(rf), dtype=float).tolist(),
            "left": np.asarray(interp.program_of(lf), dtype=float).tolist(),
        }
        save_controller(
            self.out / "controllers" / "im.json",
            InterpreterControllerSpec(
                interpreter=interp,
                programs=programs,
                metadata={"made_by": "mbn reproduce", "stage": "im", "seed": self.seed},
            ),
        )
        return {
            "connections": [str(c) for c in interp.connections],
            "connections_paper_notation": [_paper_name(str(c)) for c in interp.connections],
            "lower": np.asarray(interp.lower, dtype=float).tolist(),
            "upper": np.asarray(interp.upper, dtype=float).tolist(),
            "programs": programs,
            "neurons": int(interp.num_neurons),
            "multiplier_neurons": self.settings.multiplier_neurons,
        }

    def _im_spec(self) -> Any:
        from mbn.controllers import read_controller_spec

        return read_controller_spec(self.out / "controllers" / "im.json")

    def _pm(self) -> dict[str, Any]:
        from mbn.controllers import MBNControllerSpec, save_controller
        from mbn.experiments.evolve import robust_fitness
        from mbn.experiments.program_module import (
            MemoryReward,
            PMGenome,
            memory_reward_maximum,
            pm_fitness,
            pm_memory_fitness,
        )
        from mbn.world.engine import CameraConfig

        s = self.settings
        im_spec = self._im_spec()
        k = len(im_spec.interpreter.connections)
        genome = PMGenome(programs=k)
        camera = CameraConfig(range=s.camera_range)
        common = {
            "variants": s.pm_variants,
            "seed": self.seeds["pm_crossroad_jitter"],
            "im_substeps": im_spec.substeps,
            "camera": camera,
        }
        if s.pm_reward == "memory":
            reward = MemoryReward(approaches=s.pm_approaches, fidelity=s.pm_fidelity)
            references = (self._rf_net(), self._lf_net())
            fit = pm_memory_fitness(
                genome, im_spec.interpreter.net, reward=reward, references=references, **common
            )
            maximum = memory_reward_maximum(reward, s.pm_variants)
        else:
            fit = pm_fitness(genome, im_spec.interpreter.net, **common)
            maximum = (7 * s.pm_variants * 1.1) ** 2
        noise = self._noise("pm", genome.size, s.pm_noise_copies, s.pm_noise_sigma)
        de, _ = self.evolve(
            "pm",
            self._de_config(genome.size, s.pm_bound, s.pm_init),
            jax.jit(robust_fitness(fit, noise)),
            self.stage_key("pm"),
            s.pm_generations,
            "PM: DE generations",
        )
        pm = genome.network(jnp.asarray(de["best_genome"]))
        save_controller(
            self.out / "controllers" / "mbn.json",
            MBNControllerSpec(
                interpreter_spec=im_spec,
                program_module=pm,
                program_neurons=tuple(range(k)),
                camera=camera,
                metadata={
                    "made_by": "mbn reproduce",
                    "stage": "pm",
                    "seed": self.seed,
                    "pm_fitness": de["best_fitness"],
                },
            ),
        )
        return {
            **de,
            "reward": s.pm_reward,
            "fidelity": s.pm_fidelity if s.pm_reward == "memory" else None,
            "max_fitness": float(maximum),
            "camera_range": s.camera_range,
        }

    # -- tests --------------------------------------------------------------------------------

    def _tests(self) -> dict[str, Any]:
        from mbn.controllers import (
            CTRNNControllerSpec,
            make_controller,
            read_controller_spec,
        )
        from mbn.experiments.trials import TrialGroup, TrialSpec, run_trial_groups, summary
        from mbn.paper import published_lf, published_rf
        from mbn.world.mazes.load import load_maze

        s = self.settings
        mazes = [load_maze(s.test_maze), load_maze(s.heldout_maze)]
        ctl = self.out / "controllers"
        specs = {
            "rf": (read_controller_spec(ctl / "rf.json"), None),
            "lf": (read_controller_spec(ctl / "lf.json"), None),
            "published_rf": (CTRNNControllerSpec(net=published_rf(), behavior="right"), None),
            "published_lf": (CTRNNControllerSpec(net=published_lf(), behavior="left"), None),
            "im_rf": (read_controller_spec(ctl / "im.json"), "right"),
            "im_lf": (read_controller_spec(ctl / "im.json"), "left"),
            "mbn": (read_controller_spec(ctl / "mbn.json"), None),
        }
        rules = dict(TESTED)
        batches = [
            ("plain networks", ("rf", "lf", "published_rf", "published_lf"), s.test_seconds),
            ("interpreter", ("im_rf", "im_lf"), s.test_seconds),
            ("MBN", ("mbn",), s.mbn_seconds),
        ]
        verdicts: dict[str, dict[str, np.ndarray]] = {}
        trajectories: dict[str, Any] = {}
        bar = self._bars.task("tests", len(batches))
        for b, (what, names, seconds) in enumerate(batches):
            loaded = {n: make_controller(specs[n][0], specs[n][1], where=n) for n in names}
            first = loaded[names[0]]
            groups = []
            for n in names:
                behavior = rules[n]
                initial = "none" if behavior == "tiles" else "right"
                groups += [
                    TrialGroup(
                        n, 0, TrialSpec(behavior=behavior, initial=initial), loaded[n].initial_state
                    ),
                    TrialGroup(
                        f"{n}_jitter",
                        0,
                        TrialSpec(
                            behavior=behavior,
                            initial=initial,
                            repeats=s.jitter_per_mark,
                            exact_first=False,
                            seed=self.seeds["test_jitter"],
                        ),
                        loaded[n].initial_state,
                    ),
                    TrialGroup(
                        f"{n}_heldout",
                        1,
                        TrialSpec(
                            behavior=behavior,
                            initial=initial,
                            repeats=s.heldout_repeats,
                            seed=self.seeds["heldout_jitter"],
                        ),
                        loaded[n].initial_state,
                    ),
                ]
            for n in names[1:]:
                _same_settings(first, loaded[n], names[0], n)
            self._bars.update(bar, completed=b, info=what)
            v, result, slices, _ = run_trial_groups(
                mazes,
                groups,
                first.controller,
                seconds=seconds,
                dt=first.dt,
                sensors=first.sensors,
                camera=first.camera,
                record_every=2,
            )
            verdicts.update(v)
            for n in names:
                sl = slices[n]
                trajectories[n] = jax.tree.map(
                    lambda a, sl=sl: np.asarray(a[sl]), result.trajectory
                )
            self._bars.update(bar, completed=b + 1, info=what)
        tests = {name: summary(verdicts[name]) for name in TEST_NAMES}
        agreement = {}
        for im_name, net_name in (("im_rf", "rf"), ("im_lf", "lf")):
            for suffix in ("", "_jitter", "_heldout"):
                a = verdicts[f"{im_name}{suffix}"]["exits"]
                bb = verdicts[f"{net_name}{suffix}"]["exits"]
                same = np.all(a == bb, axis=1)
                agreement[f"{im_name}{suffix}"] = {
                    "trials": int(same.size),
                    "same_branches": int(same.sum()),
                    "rate": float(same.mean()),
                }
        details = {
            name: {
                "success": verdicts[name]["success"].astype(int).tolist(),
                "correct": verdicts[name]["correct"].astype(int).tolist(),
                "judged": verdicts[name]["judged"].astype(int).tolist(),
                "stall": np.round(verdicts[name]["stall"].astype(float), 5).tolist(),
            }
            for name in TEST_NAMES
        }
        _save_trajectories(self.out / "checkpoints" / "test_trajectories.npz", trajectories)
        return {
            "tests": tests,
            "agreement": agreement,
            "details": details,
            "mazes": {"test": s.test_maze, "heldout": s.heldout_maze},
            "protocol": {
                "junctions": 3,
                "max_stall_fraction": 0.02,
                "seconds": s.test_seconds,
                "mbn_seconds": s.mbn_seconds,
                "jitter": [0.15, 0.3, 10.0],
                "jitter_trials": f"{s.jitter_per_mark} per start mark, all jittered",
                "heldout_trials": f"each start mark, then {s.heldout_repeats - 1} jittered",
            },
        }

    def test_trajectories(self) -> dict[str, Any]:
        return _load_trajectories(self.out / "checkpoints" / "test_trajectories.npz")

    # -- results ------------------------------------------------------------------------------

    def results(self) -> dict[str, Any]:
        """``results.json``: seeds, versions, per-stage metrics, tests and the claims table."""
        stages = {name: self.stage(name) for name in STAGES}
        tests_stage = stages["tests"]
        stage_metrics = {
            name: {k: v for k, v in data.items() if k not in ("details",)}
            for name, data in stages.items()
            if name != "tests"
        }
        stage_metrics["tests"] = {
            "agreement": tests_stage["agreement"],
            "mazes": tests_stage["mazes"],
            "protocol": tests_stage["protocol"],
        }
        from mbn.experiments.claims import claims

        return {
            "seed": self.seed,
            "seeds": self.seeds,
            "quick": self.settings.quick,
            "settings": self.settings.to_dict(),
            "versions": versions(),
            "stages": stage_metrics,
            "tests": tests_stage["tests"],
            "claims": claims(stages, self.settings),
        }


# ---------------------------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------------------------


def _bind(
    search: Callable[[jax.Array, tuple[Any, ...]], jax.Array], connections: tuple[Any, ...]
) -> Callable[[jax.Array], jax.Array]:
    """The fitness of a connection search for one choice of connections."""
    return lambda population: search(population, connections)


def _tau(net: Any) -> float:
    return float(np.asarray(net.tau).reshape(-1)[0])


def _paper_name(conn: str) -> str:
    """``W[1,2]`` (0-based) -> ``W_23`` (the paper's 1-based notation)."""
    from mbn.networks.programmable import Connection

    c = Connection.parse(conn)
    return f"{c.kind}_{c.i + 1}{c.j + 1}"


def _gen_stats(state: DEState) -> tuple[float, float]:
    fit = np.asarray(state.fitness, dtype=float)
    return float(state.best_fitness), float(np.mean(fit[np.isfinite(fit)]))


def _save_checkpoint(path: Path, state: DEState, history: list[tuple[float, float]]) -> None:
    with atomic_open(path, "wb") as handle:
        np.savez(
            handle,
            population=np.asarray(state.population),
            fitness=np.asarray(state.fitness),
            best_genome=np.asarray(state.best_genome),
            best_fitness=np.asarray(state.best_fitness),
            generation=np.asarray(state.generation),
            history=np.asarray(history, dtype=float),
        )


def _load_checkpoint(path: Path) -> tuple[DEState, list[tuple[float, float]]]:
    try:
        with np.load(path) as z:
            state = DEState(
                population=jnp.asarray(z["population"]),
                fitness=jnp.asarray(z["fitness"]),
                best_genome=jnp.asarray(z["best_genome"]),
                best_fitness=jnp.asarray(z["best_fitness"]),
                generation=jnp.asarray(z["generation"]),
            )
            history = [tuple(map(float, row)) for row in z["history"]]
    except (OSError, KeyError, ValueError) as exc:
        raise MbnInputError(f"{path}: unreadable checkpoint ({exc})") from None
    return state, history  # type: ignore[return-value]


def _save_trajectories(path: Path, trajectories: dict[str, Any]) -> None:
    arrays = {}
    for name, traj in trajectories.items():
        for f in ("t", "pose", "camera", "tile", "stalled", "v", "w"):
            arrays[f"{name}.{f}"] = np.asarray(getattr(traj, f))
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)  # type: ignore[arg-type]
    with atomic_open(path, "wb") as handle:
        handle.write(buf.getvalue())


def _load_trajectories(path: Path) -> dict[str, Any]:
    from types import SimpleNamespace

    out: dict[str, dict[str, np.ndarray]] = {}
    with np.load(path) as z:
        for k in z.files:
            name, f = k.split(".", 1)
            out.setdefault(name, {})[f] = z[k]
    return {name: SimpleNamespace(**fields) for name, fields in out.items()}


def _same_settings(a: Any, b: Any, na: str, nb: str) -> None:
    """Controllers run in one batch must share their run settings."""
    sa, sb = a.spec, b.spec
    get = lambda s: getattr(s, "interpreter_spec", s)  # noqa: E731
    for attr in ("dt", "substeps", "method", "motor", "sensors"):
        if getattr(get(sa), attr) != getattr(get(sb), attr):
            raise MbnInputError(f"{na} and {nb} differ in {attr}: they cannot run in one batch")


def _stage_line(name: str, data: dict[str, Any]) -> str:
    if name == "multiplier":
        m = data["metrics"]
        return f"{data['source']}, max |error| on the grid {m['max_abs_error_grid']:.4f}"
    if name in ("rf", "lf", "pm"):
        extra = f" ({', '.join(data['connections'])})" if name == "lf" else ""
        gens = data["generations"]
        return f"best fitness {data['best_fitness']:.2f} after {gens} generations{extra}"
    if name == "lf_search":
        return f"chose {', '.join(data['chosen'])}"
    if name == "im":
        return f"programmable {', '.join(data['connections'])}; {data['neurons']} neurons"
    if name == "tests":
        t = data["tests"]
        return ", ".join(f"{n} {t[n]['successes']}/{t[n]['trials']}" for n, _ in TESTED)
    return "done"
