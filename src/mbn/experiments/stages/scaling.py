"""Stages ``mbn_k2`` .. ``mbn_k6``: MBNs of K = 2 .. 6 behaviours, each grown from the one
before by one tile kind and one program (``docs/scaling.md``).

The interpreter of ``im_full`` stays fixed (its sha256 checked before and after every K) and so
do its programs (``controllers/im_full_programs.json``: RF's, LF's and the ``programs`` stage's
new rules). The MBN of K behaviours is that interpreter with a code program module (as the
three-behaviour MBN's, :func:`~mbn.experiments.stages.mbn3.evolve_code_pm`) for the first K
rules of ``[scaling] rules`` — one camera input and one code neuron per tile kind of 1 .. K
colours — whose readout's columns are the K programs. Adding a behaviour adds a program, a camera
input, a code neuron and a column; nothing else changes. With ``[scaling] incremental`` the
K-behaviour program module's DE starts from the (K-1)-behaviour one's final population, its
weights kept in place and the new neuron's and input's genes drawn as a first generation's are
(:func:`grow_population`); otherwise from a random population. With maze episodes its final
choice drives the robot: up to ``[validation] attempts`` program modules, each MBN judged in the
validation split of its tile family (``tiles{K}``), the best kept (as ``mbn3``).

Each stage records the program module's DE (its evaluations: the behaviour's marginal cost
beside the new rule's program search), the codes it latches and how far each is from its
target (the code error), the validation, and the interpreter's digest.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import jax
import numpy as np

from mbn.config import Locator, Settings, setting
from mbn.controllers import (
    InterpreterControllerSpec,
    MBNControllerSpec,
    read_controller_spec,
    save_controller,
)
from mbn.errors import MbnInputError
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.pipeline.results import Record, optional
from mbn.experiments.stages.common import (
    MADE_BY,
)
from mbn.experiments.stages.generalization import GeneralizationStage, Judged
from mbn.experiments.stages.im_full import IMFullStage
from mbn.experiments.stages.keys import KEYS
from mbn.experiments.stages.mbn3 import CodePM, attempts_record, choose_code_mbn
from mbn.experiments.stages.programs import check_digest
from mbn.experiments.stages.records import History, Validation
from mbn.experiments.stages.settings import DESettings
from mbn.world.engine import CameraConfig
from mbn.world.rules import parse_rule, parse_rules

__all__ = [
    "KS",
    "SCALING_RULES",
    "STAGE_CLASSES",
    "MBNKResult",
    "MBNKStage",
    "ScalingSettings",
    "code_errors",
    "grow_population",
    "scaling_stages",
]

_DOC = "docs/scaling.md"

#: The rules in the order their behaviours are added: a tile of k colours puts the k-th in force.
SCALING_RULES = ("right", "left", "straight-right", "straight-left", "right-left", "left-right")
#: The numbers of behaviours of the MBNs grown (one stage each).
KS = (2, 3, 4, 5, 6)
#: Folded into an attempt's key for the new genes of a grown population.
GROW_KEY = 500


@dataclass(frozen=True)
class ScalingSettings(Settings):
    """The MBNs of K behaviours: the order of their rules and their program modules."""

    section = "scaling"
    # a run recorded before the generations driving the robot existed ran none
    recorded_before: ClassVar[dict[str, Any]] = {"maze_generations": 0}
    rules: tuple[str, ...] = setting(
        SCALING_RULES,
        doc="the rule a tile of 1, 2, ... 6 colours puts in force, in the order the behaviours "
        "are added (RF's and LF's first; the others learned by [programs] rules)",
        source=_DOC,
    )
    generations: int = setting(
        1500,
        doc="DE generations of each program module (robot-free)",
        low=0,
        high=100_000,
        source="as [mbn3] generations",
    )
    incremental: bool = setting(
        True,
        doc="each program module's DE starts from the one before's final population, the new "
        "neuron's and input's genes drawn at random (false: from a random population)",
        source=_DOC,
    )
    bound: float = setting(10.0, doc="genes are kept in [-bound, bound]", low=0.0, high=1e4)
    switch_seconds: float = setting(
        0.3,
        doc="how soon after a tile comes into view the code must have switched",
        unit="s",
        low=0.0,
        high=10.0,
        source="as [mbn3] switch_seconds",
    )
    camera_range: float = setting(
        0.8, doc="the camera's range", unit="m", low=0.1, high=10.0, source="as [mbn3]"
    )
    maze_generations: int = setting(
        50,
        doc="where an MBN misses its validation target: DE generations of its program module "
        "driving the robot in mazes of the family of its K tile kinds (train split), the "
        "better MBN by validation kept (0: none)",
        low=0,
        high=100_000,
        source="as [mbn3] maze_generations",
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        try:
            names = [parse_rule(r).name for r in self.rules]
        except MbnInputError as exc:
            raise MbnInputError(f"scaling.rules: {exc}") from None
        if len(names) != max(KS) or len(set(names)) != len(names):
            raise MbnInputError(
                f"scaling.rules: {max(KS)} different rules, one per tile kind, got {names}"
            )
        if names[:2] != ["right", "left"]:
            raise MbnInputError(
                "scaling.rules: the first two are RF's and LF's rules, right and left (the "
                f"interpreter's own programs), got {names[:2]}"
            )

    def check_names(self, sections: Any, where: Locator) -> None:
        # every rule past the first two is learned by the programs stage
        if "programs" not in sections:
            return
        learned = parse_rules(sections["programs"].rules, "programs.rules")
        for text in self.rules[2:]:
            rule = parse_rule(text).name
            if rule not in learned:
                raise MbnInputError(
                    f"{where(self.section, 'rules')}: {rule} has no program: [programs] rules "
                    f"learns {', '.join(learned)}"
                )


def grow_population(population: np.ndarray, kinds: int, key: jax.Array, bound: float) -> np.ndarray:
    """A (K+1)-kind program module's first population from a K-kind one's (``population``:
    ``(P, size(K))``, :class:`~mbn.experiments.program_module.PMGenome` with ``kinds`` code
    neurons and camera inputs): each member's W, WE and biases kept in their places, the new
    neuron's row and column, its input's column and its bias drawn uniformly in ``[-bound,
    bound]`` (as DE's first generation)."""
    k, n = kinds, kinds + 1
    p = population.shape[0]
    if population.shape[1] != k * k + k * k + k:
        raise MbnInputError(
            f"grow_population: a {k}-kind population has {2 * k * k + k} genes, got "
            f"{population.shape[1]}"
        )
    draw = np.asarray(jax.random.uniform(key, (p, 2 * n * n + n), minval=-bound, maxval=bound))
    draw = draw.astype(population.dtype)
    W = draw[:, : n * n].reshape(p, n, n).copy()
    WE = draw[:, n * n : 2 * n * n].reshape(p, n, n).copy()
    bias = draw[:, 2 * n * n :].copy()
    W[:, :k, :k] = population[:, : k * k].reshape(p, k, k)
    WE[:, :k, :k] = population[:, k * k : 2 * k * k].reshape(p, k, k)
    bias[:, :k] = population[:, 2 * k * k :]
    return np.concatenate([W.reshape(p, -1), WE.reshape(p, -1), bias], axis=1)


def code_errors(latched: list[np.ndarray | None]) -> list[float]:
    """How far the code latched after each tile kind is from its target ``e_k``: the largest
    absolute difference over the code neurons (1 where the program module never settles)."""
    kinds = len(latched)
    return [
        1.0 if c is None else float(np.max(np.abs(np.asarray(c) - np.eye(kinds)[k])))
        for k, c in enumerate(latched)
    ]


@dataclass(frozen=True, kw_only=True)
class MBNKResult(Record):
    """What a stage ``mbn_kK`` records (``stages/mbn_kK.json``): K, its tile rules, the program
    module's DE (best genome and fitness, generations, history, the evaluations it took over
    every attempt), whether it grew from the one before, the codes it latches and their errors,
    the initial rule, the interpreter's digest checked, and with several attempts the kept
    one's validation and every attempt; with ``[scaling] maze_generations``, the robot
    evaluations of the generations driving the robot (``maze_evaluations``: genomes evaluated,
    each on one draw of maze episodes) and the kept attempt's ``maze`` record
    (:func:`~mbn.experiments.stages.mbn3.choose_code_mbn`)."""

    k: int
    tile_rules: list[str]
    best_genome: list[float]
    best_fitness: float
    generations: int
    history: History
    evaluations: int
    grown: bool
    latched_codes: dict[str, Any]
    code_errors: dict[str, float]
    initial: str | None
    sha256: str
    sha256_checked: bool
    validation: Validation | None = optional()
    attempts: list[dict[str, Any]] | None = optional()
    chosen_attempt: int | None = optional()
    maze_evaluations: int = optional(0)
    maze: dict[str, Any] | None = optional()


class MBNKStage(Stage[MBNKResult]):
    """The MBN of ``k`` behaviours; one subclass per K (:data:`STAGE_CLASSES`,
    :func:`scaling_stages`) names the stage ``mbn_kK``, its key, its file and what it needs."""

    settings = None
    result = MBNKResult
    k: ClassVar[int] = 0

    def run(self, ctx: StageContext) -> MBNKResult:
        s = ctx.section(ScalingSettings)
        k = self.k
        path = ctx.rundir.controller_file("im_full_programs")
        im_spec = read_controller_spec(path)
        if not isinstance(im_spec, InterpreterControllerSpec):
            raise MbnInputError(f"{path}: not an interpreter")
        digest = ctx.read(IMFullStage).sha256
        check_digest(im_spec.interpreter, digest, self.name)
        rules = tuple(parse_rule(r).name for r in s.rules[:k])
        missing = [r for r in rules if r not in im_spec.programs]
        if missing:
            raise MbnInputError(
                f"scaling.rules: {path} has no program for {', '.join(missing)} (it has "
                f"{', '.join(im_spec.programs)})"
            )
        meta = {"made_by": MADE_BY, "stage": self.name, "seed": ctx.seed, "sha256": digest}
        popsize = ctx.section(DESettings).popsize
        grown = s.incremental and k > min(KS)

        def first(key: jax.Array) -> np.ndarray:
            """The (K-1)-behaviour program module's final population, grown by a tile kind."""
            before = ctx.rundir.load_checkpoint(_pm_checkpoint(ctx, k - 1)).state
            population = np.asarray(before.population, float)
            return grow_population(population, k - 1, jax.random.fold_in(key, GROW_KEY), s.bound)

        tries, chosen = choose_code_mbn(
            ctx,
            self.name,
            im_spec,
            rules,
            CameraConfig(range=s.camera_range),
            meta,
            generations=s.generations,
            bound=s.bound,
            switch_seconds=s.switch_seconds,
            first=first if grown else None,
            maze_generations=s.maze_generations,
        )
        best = tries[chosen]
        save_controller(ctx.rundir.controller_file(self.name), best["spec"])
        again = read_controller_spec(ctx.rundir.controller_file(self.name))
        assert isinstance(again, MBNControllerSpec)
        check_digest(again.interpreter_spec.interpreter, digest, f"controllers/{self.name}.json")
        pm: CodePM = best["pm"]
        errors = code_errors([None if c is None else np.asarray(c) for c in pm.latched.values()])
        run = pm.run
        return MBNKResult.from_json(
            {
                "k": k,
                "tile_rules": list(rules),
                "best_genome": run.data["best_genome"],
                "best_fitness": run.data["best_fitness"],
                "generations": s.generations,
                "history": run.data["history"],
                "evaluations": popsize * (s.generations + 1) * len(tries),
                "maze_evaluations": popsize
                * (s.maze_generations + 1)
                * sum(1 for t in tries if t["maze"] is not None),
                "grown": grown,
                "latched_codes": pm.latched,
                "code_errors": dict(zip(rules, errors, strict=True)),
                "initial": None if best["spec"].initial is None else best["spec"].initial.rule,
                "sha256": digest,
                "sha256_checked": True,
                **attempts_record(tries, chosen),
                **({"maze": best["maze"]} if best["maze"] else {}),
            }
        )

    def summary(self, result: MBNKResult) -> str:
        worst = max(result.code_errors.values())
        return (
            f"{result.k} behaviours ({', '.join(result.tile_rules)}): program reward "
            f"{result.best_fitness:.4f}, worst code error {worst:.3f}"
        )


def _pm_checkpoint(ctx: StageContext, k: int) -> str:
    """The checkpoint of the program module stage ``mbn_kK`` kept (its chosen attempt's)."""
    data = ctx.rundir.read_stage(f"mbn_k{k}")
    a = data.get("chosen_attempt") or 0
    return f"mbn_k{k}_pm" + (f"_attempt{a}" if a else "")


def _stage_class(k: int) -> type[MBNKStage]:
    name = f"mbn_k{k}"
    attributes: dict[str, Any] = {
        "k": k,
        "name": name,
        "key_id": KEYS[f"scaling.{name}"],
        "outputs": (f"controllers/{name}.json",),
        "needs": ("im_full", "programs") + ((f"mbn_k{k - 1}",) if k > min(KS) else ()),
        "__module__": __name__,
        "__doc__": f"Stage ``{name}``: the MBN of {k} behaviours.",
    }
    return type(f"MBNK{k}Stage", (MBNKStage,), attributes)


MBNK2Stage = _stage_class(2)
MBNK3Stage = _stage_class(3)
MBNK4Stage = _stage_class(4)
MBNK5Stage = _stage_class(5)
MBNK6Stage = _stage_class(6)
#: The stage class of each K.
STAGE_CLASSES: dict[int, type[MBNKStage]] = {
    2: MBNK2Stage,
    3: MBNK3Stage,
    4: MBNK4Stage,
    5: MBNK5Stage,
    6: MBNK6Stage,
}


def scaling_stages() -> list[MBNKStage]:
    """The stages ``mbn_k2`` .. ``mbn_k6``, in order."""
    return [STAGE_CLASSES[k]() for k in KS]


class ScalingGeneralization(GeneralizationStage):
    """The MBN of each K judged on the test split of its tile family (``tiles{K}``; and its
    zero-shot suite where the family has one), on the test split of the switch's family
    (``turns{K}``: tiles 0 to 3 cells before junctions and on corners), and, for K > 2, on the
    test split of the family of K - 1 behaviours too: the behaviours already there when the
    K-th was added (forgetting, against the MBN of K - 1 on the same mazes and trials)."""

    key_id = KEYS["scaling.generalization"]
    needs = tuple(f"mbn_k{k}" for k in KS)

    def controllers(self, ctx: StageContext) -> tuple[Judged, ...]:
        out: list[Judged] = []
        for k in KS:
            out.append(Judged(f"mbn_k{k}", f"mbn_k{k}", "tiles"))
            # the switch: tiles 0..3 cells before junctions and in the middle of turns
            out.append(Judged(f"mbn_k{k}_turns", f"mbn_k{k}", "tiles", family=f"turns{k}"))
            if k > min(KS):
                out.append(
                    Judged(
                        f"mbn_k{k}_on_tiles{k - 1}", f"mbn_k{k}", "tiles", family=f"tiles{k - 1}"
                    )
                )
        return tuple(out)
