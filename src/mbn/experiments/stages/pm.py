"""Stage ``pm``: the program module, evolved with the interpreter fixed (paper 3.2), by default on
the program reward without the robot and then validated in it (``docs/reproduce.md``); the robot
rewards: ``docs/experiments.md``."""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from mbn.config import Locator, Settings, setting
from mbn.controllers import (
    InterpreterControllerSpec,
    MBNControllerSpec,
    PMInitial,
    read_controller_spec,
    save_controller,
)
from mbn.errors import MbnInputError
from mbn.experiments.crossroads import EPISODE_FITNESS_MAX
from mbn.experiments.evolve import robust_fitness
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.pipeline.results import Record, optional
from mbn.experiments.program_module import (
    MemoryReward,
    PMGenome,
    latch_after_tile,
    memory_reward_maximum,
    pm_fitness,
    pm_memory_fitness,
    pm_program_fitness,
    start_mismatch,
)
from mbn.experiments.stages.common import (
    MADE_BY,
    de_config,
    read_network,
    stage_perturbations,
    validate,
    validation_figure,
)
from mbn.experiments.stages.keys import KEYS
from mbn.experiments.stages.lf import ATTEMPT_KEY
from mbn.experiments.stages.pm_mazes import mend_in_mazes
from mbn.experiments.stages.records import History, Validation
from mbn.experiments.stages.rf import evolution_summary
from mbn.experiments.stages.settings import ValidationSettings
from mbn.world.engine import CameraConfig
from mbn.world.mazes.builtin import APPROACHES, check_approaches
from mbn.world.sensors import NoiseConfig

__all__ = ["LatchedStart", "PMResult", "PMSettings", "PMStage"]

#: The program-reward phase before a robot reward (``shaping_generations``) of attempt a draws
#: from ``fold_in(attempt's key, SHAPING_KEY)``.
SHAPING_KEY = 7
#: Crossroad kinds of the paper's PM reward (its two trials run on all seven).
_PAPER_KINDS = 7
#: The MBN starts in the state its PM latches after a one-colour tile (meant to be RF's).
INITIAL_TILE = 1
#: The latched program is reported as RF's when no value is further than this from it.
INITIAL_PROGRAM_TOL = 0.05


@dataclass(frozen=True)
class PMSettings(Settings):
    """The program module (PM): a CTRNN from the camera's tile readings to the program."""

    section = "pm"
    # a run recorded before the generations driving the robot existed ran none
    recorded_before: ClassVar[dict[str, Any]] = {"maze_generations": 0}
    generations: int = setting(
        300, doc="DE generations", low=0, high=100_000, source="docs/reproduce.md"
    )
    reward: str = setting(
        "programs",
        doc="programs: latch the interpreter's programs, without the robot; memory: the paper's "
        "product with switching, memory and rest episodes; paper: its two trials",
        choices=("programs", "memory", "paper"),
        source="paper 3.2; docs/reproduce.md (the PM's reward); docs/experiments.md",
    )
    variants: int = setting(1, doc="robot rewards: starts per episode", low=1, high=100)
    bound: float = setting(10.0, doc="genes are kept in [-bound, bound]", low=0.0, high=1e4)
    init: float = setting(
        10.0, doc="the first generation is drawn in [-init, init] (0 < init <= bound)", low=0.0
    )
    shaping_generations: int = setting(
        0,
        doc="with a robot reward (memory, paper): DE generations on the program reward first, "
        "whose population the robot's DE then starts from (0: a random one)",
        low=0,
        high=100_000,
        source="docs/reproduce.md (the PM's reward)",
    )
    switch_seconds: float = setting(
        0.3,
        doc="program reward: how soon the program must change once a tile is in view",
        unit="s",
        low=0.0,
        high=1.5,
        source="docs/reproduce.md (the PM's reward)",
    )
    perturbation_sigma: float = setting(
        1.0,
        doc="robot rewards: standard deviation of the PM's weight perturbations",
        low=0.0,
        high=1e4,
    )
    perturbation_copies: int = setting(
        0, doc="robot rewards: perturbed copies per genome (0: none)", low=0, high=100
    )
    approaches: tuple[str, ...] = setting(
        ("south", "west", "east"),
        doc="how the robot enters the crossroads of the memory and rest episodes",
        choices=APPROACHES,
        source="docs/experiments.md",
    )
    fidelity: float = setting(
        2.0,
        doc="weight of the motor mismatch with RF/LF in the memory reward",
        low=0.0,
        source="docs/experiments.md",
    )
    camera_range: float = setting(
        0.8,
        doc="how far the camera sees a tile",
        unit="m",
        low=0.01,
        source="docs/experiments.md (the camera range)",
    )
    maze_generations: int = setting(
        50,
        doc="where the MBN misses its validation target: DE generations of the PM driving the "
        "robot in mazes of the tiles2 family's train split ([episodes] pool, mazes, starts, "
        "seconds, redraw), from its reward's last population; the better MBN by validation is "
        "kept (0: none)",
        low=0,
        high=100_000,
        source="docs/generalization.md (the program module driving the robot: 50 against 0 and "
        "150, seeds 30-34)",
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        if not 0 < self.init <= self.bound:
            raise MbnInputError(f"pm.init must be in (0, pm.bound], got {self.init!r}")
        if self.reward == "programs" and self.shaping_generations:
            raise MbnInputError(
                "pm.shaping_generations applies to the robot's rewards (pm.reward = memory or "
                "paper), not to pm.reward = programs"
            )
        try:
            check_approaches(self.approaches)
        except MbnInputError as exc:
            raise MbnInputError(f"pm.{exc}") from None

    def check_names(self, sections: Mapping[str, Settings], where: Locator) -> None:
        # a robot reward under the run's [noise] is refused by the stage: refuse it up front
        noise = sections.get("noise")
        if self.reward != "programs" and isinstance(noise, NoiseConfig) and noise.enabled:
            raise MbnInputError(
                f"{where(self.section, 'reward')} = {self.reward!r}: a PM evolved on robot "
                "episodes under [noise] is not supported; the default reward ('programs') needs "
                "no robot (docs/noise.md)"
            )


@dataclass(frozen=True, kw_only=True)
class LatchedStart(Record):
    """The MBN's start as ``stages/pm.json`` records it (``initial``): the tile shown, the rule
    the latched state stands for (None: it did not settle), RF's program, whether it settled
    and, when it did, how soon, the state, the program it sends, its motor mismatches against
    RF and LF, its largest difference from RF's program and whether that is within
    ``tolerance``. Read with :meth:`~mbn.experiments.pipeline.results.Record.from_json`."""

    tile: int
    rule: str | None
    rf_program: list[float] | None
    settled: bool
    settled_after_seconds: float | None = None
    potentials: list[float] | None = None
    program: list[float] | None = None
    mismatch_rf: float | None = None
    mismatch_lf: float | None = None
    max_distance_to_rf_program: float | None = None
    is_rf_program: bool = False
    tolerance: float | None = None


@dataclass(frozen=True, kw_only=True)
class PMResult(Record):
    """What the ``pm`` stage records (``stages/pm.json``): the kept attempt's DE run (best
    genome and fitness, generations, history), the MBN's initial state, the shaping run (None
    without one), the program reward, the validation, every attempt in brief, and the reward's
    settings and ceiling; with ``[pm] maze_generations``, ``maze``: the kept attempt's
    generations driving the robot in mazes, run where its MBN missed the validation target
    (:func:`~mbn.experiments.stages.pm_mazes.maze_record`, with that MBN's ``validation`` and
    whether it was ``kept``, i.e. validated better: then its ``best_genome`` is the MBN's program
    module; None where they did not run)."""

    best_genome: list[float]
    best_fitness: float
    generations: int
    history: History
    initial: dict[str, Any]
    shaping: dict[str, Any] | None
    program_reward: float | None
    validation: Validation
    attempts: list[dict[str, Any]]
    chosen_attempt: int
    reward: str
    fidelity: float | None
    switch_seconds: float
    max_fitness: float
    camera_range: float
    maze: dict[str, Any] | None = optional()


class PMStage(Stage[PMResult]):
    name = "pm"
    key_id = KEYS["pm"]
    outputs = ("controllers/mbn.json",)
    needs = ("rf", "lf", "im")
    settings = PMSettings
    result = PMResult

    def run(self, ctx: StageContext) -> PMResult:
        s: PMSettings = ctx.settings
        im_spec = read_controller_spec(ctx.rundir.controller_file("im"))
        if not isinstance(im_spec, InterpreterControllerSpec):
            raise MbnInputError(f"{ctx.rundir.controller_file('im')}: not an interpreter")
        k = len(im_spec.interpreter.connections)
        genome = PMGenome(programs=k)
        camera = CameraConfig(range=s.camera_range)
        common: dict[str, Any] = {
            "variants": s.variants,
            "seed": ctx.seeds["pm_crossroad_jitter"],
            "im_substeps": im_spec.substeps,
            "camera": camera,
        }
        references = (read_network(ctx, "rf"), read_network(ctx, "lf"))
        programs = (tuple(im_spec.programs["right"]), tuple(im_spec.programs["left"]))
        latch = jax.jit(
            pm_program_fitness(genome, programs, reward=MemoryReward(), switch=s.switch_seconds)
        )
        if s.reward == "programs":
            fitness, maximum = latch, 0.0
        else:
            if s.reward == "memory":
                reward = MemoryReward(approaches=s.approaches, fidelity=s.fidelity)
                fit = pm_memory_fitness(
                    genome, im_spec.interpreter.net, reward=reward, references=references, **common
                )
                maximum = memory_reward_maximum(reward, s.variants)
            else:
                fit = pm_fitness(genome, im_spec.interpreter.net, **common)
                maximum = (_PAPER_KINDS * s.variants * EPISODE_FITNESS_MAX) ** 2
            noise = stage_perturbations(
                ctx, genome.size, s.perturbation_copies, s.perturbation_sigma
            )
            fitness = jax.jit(robust_fitness(fit, noise))
        config = de_config(ctx, genome.size, s.bound, s.init)
        attempts: list[dict[str, Any]] = []
        for a in range(ctx.section(ValidationSettings).attempts):
            name = "pm" if a == 0 else f"pm_attempt{a}"
            key = ctx.key if a == 0 else jax.random.fold_in(ctx.key, ATTEMPT_KEY + a)
            suffix = f" (attempt {a + 1})" if a else ""
            population = None
            shaped = None
            if s.shaping_generations:
                pre = ctx.evolve(
                    f"{name}_shaping",
                    config,
                    latch,
                    jax.random.fold_in(key, SHAPING_KEY),
                    s.shaping_generations,
                    "PM: generations on the program reward" + suffix,
                )
                population = np.asarray(pre.state.population)
                shaped = {
                    "best_fitness": pre.data["best_fitness"],
                    "generations": s.shaping_generations,
                    "history": pre.data["history"],
                }
            de = ctx.evolve(
                name, config, fitness, key, s.generations, "PM: DE generations" + suffix, population
            )
            kept, maze = de.data["best_genome"], None

            def mbn(genes: Any, fitness: float) -> tuple[MBNControllerSpec, dict[str, Any]]:
                pm = genome.network(jnp.asarray(genes))
                initial, start = _initial_state(
                    pm, k, im_spec, references, MemoryReward().see, camera
                )
                spec = MBNControllerSpec(
                    interpreter_spec=im_spec,
                    program_module=pm,
                    program_neurons=tuple(range(k)),
                    camera=camera,
                    initial=initial,
                    metadata={
                        "made_by": MADE_BY,
                        "stage": "pm",
                        "seed": ctx.seed,
                        "pm_fitness": fitness,
                        "pm_reward": s.reward,
                        "initial": start,
                    },
                )
                return spec, start

            spec, start = mbn(kept, de.data["best_fitness"])
            # The whole MBN on the validation mazes, judged from its start.
            check = validate(ctx, spec, "tiles")
            if s.maze_generations and not check["meets_target"]:
                # it misses its target: the PM's last generations drive the robot in mazes,
                # from the reward's population, and the better MBN by validation is kept
                maze, (driven, driven_start) = mend_in_mazes(
                    ctx,
                    f"{name}_mazes",
                    spec,
                    check,
                    genome,
                    ("right", "left"),
                    np.asarray(de.state.population),
                    key,
                    s.maze_generations,
                    s.bound,
                    "PM: generations driving the robot in mazes" + suffix,
                    functools.partial(mbn, fitness=de.data["best_fitness"]),
                )
                if maze["kept"]:
                    kept, spec, start = maze["best_genome"], driven, driven_start
                    check = maze["validation"]
            # how closely this PM latches the programs (the program reward, 0 at best)
            program_error = (
                de.data["best_fitness"]
                if s.reward == "programs" and not (maze and maze["kept"])
                else float(latch(jnp.asarray([kept]))[0])
            )
            attempts.append(
                {
                    "data": de.data,
                    "shaping": shaped,
                    "program_reward": program_error,
                    "initial": start,
                    "spec": spec,
                    "validation": check,
                    "maze": maze,
                }
            )
            if check["meets_target"]:
                break
        chosen = max(
            range(len(attempts)),
            key=lambda i: (
                validation_figure(attempts[i]["validation"]),
                attempts[i]["data"]["best_fitness"],
                -i,
            ),
        )
        best = attempts[chosen]
        save_controller(ctx.rundir.controller_file("mbn"), best["spec"])
        return PMResult.from_json(
            {
                **best["data"],
                "initial": best["initial"],
                "shaping": best["shaping"],
                "program_reward": best["program_reward"],
                "validation": best["validation"],
                "attempts": [
                    {
                        "best_fitness": x["data"]["best_fitness"],
                        "program_reward": x["program_reward"],
                        "initial_rule": x["initial"]["rule"],
                        "validation": x["validation"],
                        **(
                            {
                                "maze_fitness": x["maze"]["best_fitness"],
                                "maze_kept": x["maze"]["kept"],
                            }
                            if x["maze"] is not None
                            else {}
                        ),
                    }
                    for x in attempts
                ],
                "chosen_attempt": chosen,
                "reward": s.reward,
                "fidelity": s.fidelity if s.reward == "memory" else None,
                "switch_seconds": s.switch_seconds,
                "max_fitness": float(maximum),
                "camera_range": s.camera_range,
                "maze": best["maze"],
            }
        )

    def summary(self, data: PMResult) -> str:
        head = (
            evolution_summary(data, label="program reward", fmt=".1e")
            if data.reward == "programs"
            else evolution_summary(data)
        )
        if data.maze is not None:
            maze = data.maze
            head += (
                f"; then {maze['generations']} generations driving the robot in "
                f"{maze['family']} mazes"
            )
            if "kept" in maze:  # recorded since the better MBN by validation is kept
                head += (
                    f" ({'kept' if maze['kept'] else 'not kept'}: "
                    f"{maze['validation']['mazes_at_target']} validation mazes at target)"
                )
        start = data.initial
        if start["rule"] is None:
            return f"{head}; starts at rest (no settled state)"
        program = ", ".join(f"{v:.3f}" for v in start["program"])
        return f"{head}; starts as {start['rule']} ({program})"


def _initial_state(
    pm: Any,
    k: int,
    im_spec: InterpreterControllerSpec,
    references: tuple[Any, Any],
    see: float,
    camera: CameraConfig,
) -> tuple[PMInitial | None, dict[str, Any]]:
    """The MBN's start: the state the evolved PM latches after a one-colour tile (shown for
    ``see`` seconds, then nothing until it settles), and the rule it stands for: the one of the
    network (RF or LF) the MBN started there drives closer to, by the mean motor mismatch on the
    crossroads without tiles (:func:`start_mismatch`); and what ``results.json`` records of it,
    with the program it sends against RF's."""
    latch = latch_after_tile(pm, INITIAL_TILE, range(k), see=see)
    right = im_spec.programs.get("right")
    record: dict[str, Any] = {
        "tile": INITIAL_TILE,
        "rule": None,
        "rf_program": list(right) if right is not None else None,
    }
    if latch is None:
        return None, {**record, "settled": False}
    m_right, m_left = start_mismatch(
        pm,
        im_spec.interpreter.net,
        latch.potentials,
        references,
        range(k),
        im_substeps=im_spec.substeps,
        camera=camera,
    )
    rule = "right" if m_right <= m_left else "left"
    distance = (
        float(max(abs(a - b) for a, b in zip(latch.program, right, strict=True)))
        if right is not None
        else None
    )
    record.update(
        {
            "rule": rule,
            "settled": True,
            "settled_after_seconds": latch.seconds,
            "potentials": [float(v) for v in latch.potentials],
            "program": [round(float(v), 6) for v in latch.program],
            "mismatch_rf": round(m_right, 6),
            "mismatch_lf": round(m_left, 6),
            "max_distance_to_rf_program": distance,
            "is_rf_program": distance is not None and distance <= INITIAL_PROGRAM_TOL,
            "tolerance": INITIAL_PROGRAM_TOL,
        }
    )
    return PMInitial(rule, tuple(float(v) for v in latch.potentials)), record
