"""Stage ``mbn3``: a three-behaviour MBN, learned incrementally: a program module that maps one-,
two- and three-colour tiles to the RF, LF and straight-right programs of the fixed ``im_full``
interpreter (its sha256 checked), evolved by DE without the robot on the program reward of
``mbn reproduce`` (:func:`mbn.experiments.program_module.code_fitness`), for three tile kinds.

The PM latches a code, one neuron per behaviour; its output layer, a fixed readout whose
columns are the stored programs (``MBNControllerSpec.readout``), sends the code's program to
the interpreter. Adding a behaviour adds a camera input, a code neuron and a column; the
interpreter is not touched. The MBN starts as the behaviour of a one-colour tile (the state its
PM latches after one)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
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
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.pipeline.results import Record, optional
from mbn.experiments.program_module import (
    MemoryReward,
    PMGenome,
    code_fitness,
    latch_after_tile,
    tile_sequences,
)
from mbn.experiments.stages.common import (
    MADE_BY,
    de_config,
    maze_episodes,
    validate,
    validation_figure,
)
from mbn.experiments.stages.im_full import IMFullStage
from mbn.experiments.stages.keys import KEYS
from mbn.experiments.stages.lf import ATTEMPT_KEY
from mbn.experiments.stages.pm_mazes import mend_in_mazes
from mbn.experiments.stages.programs import check_digest
from mbn.experiments.stages.records import History, Validation
from mbn.experiments.stages.settings import ValidationSettings
from mbn.networks.ctrnn import CTRNN
from mbn.world.engine import CameraConfig
from mbn.world.rules import parse_rule, parse_rules

__all__ = [
    "CodePM",
    "MBN3Result",
    "MBN3Settings",
    "MBN3Stage",
    "attempts_record",
    "choose_code_mbn",
    "code_mbn",
    "code_pm_fitness",
    "evolve_code_pm",
    "latched_codes",
]


@dataclass(frozen=True)
class MBN3Settings(Settings):
    """The three-behaviour MBN."""

    section = "mbn3"
    # a run recorded before the generations driving the robot existed ran none
    recorded_before: ClassVar[dict[str, Any]] = {"maze_generations": 0}
    tile_rules: tuple[str, ...] = setting(
        ("right", "left", "straight-right"),
        doc="the rule a tile of 1, 2, 3 colours puts in force (programs of im_full_programs)",
        source="docs/behaviours.md",
    )
    generations: int = setting(
        1500,
        doc="DE generations",
        low=0,
        high=100_000,
        source="docs/behaviours.md (300: the third code latched at 0.59; 1500: 0.995, 18 s)",
    )
    bound: float = setting(10.0, doc="genes are kept in [-bound, bound]", low=0.0, high=1e4)
    switch_seconds: float = setting(
        0.3,
        doc="how soon after a tile comes into view the code must have switched",
        unit="s",
        low=0.0,
        high=10.0,
        source="as [pm] switch_seconds",
    )
    camera_range: float = setting(
        0.8, doc="the camera's range", unit="m", low=0.1, high=10.0, source="as [pm]"
    )
    maze_generations: int = setting(
        50,
        doc="where the MBN misses its validation target: DE generations of the program module "
        "driving the robot in mazes of the tiles3 family's train split, from its reward's last "
        "population; the better MBN by validation is kept (0: none)",
        low=0,
        high=100_000,
        source="as [pm] maze_generations",
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        try:
            names = [parse_rule(r).name for r in self.tile_rules]
        except MbnInputError as exc:
            raise MbnInputError(f"mbn3.tile_rules: {exc}") from None
        if len(names) != 3:
            raise MbnInputError(f"mbn3.tile_rules: one rule per tile kind (3), got {len(names)}")
        if len(set(names)) != len(names):
            raise MbnInputError("mbn3.tile_rules: a rule is listed twice")

    def check_names(self, sections: Mapping[str, Settings], where: Locator) -> None:
        # each rule has a program: RF's, LF's or one the programs stage learns
        if "programs" not in sections:
            return
        programs: Any = sections["programs"]
        learned = parse_rules(programs.rules, "programs.rules")
        for text in self.tile_rules:
            rule = parse_rule(text).name
            if rule not in ("right", "left", *learned):
                raise MbnInputError(
                    f"{where(self.section, 'tile_rules')}: {rule} has no program: right and "
                    f"left are RF's and LF's, [programs] rules learns {', '.join(learned)}"
                )


@dataclass(frozen=True)
class CodePM:
    """A program module evolved to latch one code per tile kind (:func:`evolve_code_pm`): its
    network (float64), DE's result, and the code it latches after each tile kind's rule."""

    network: CTRNN
    run: Any
    latched: dict[str, list[float] | None]


def evolve_code_pm(
    ctx: StageContext,
    name: str,
    rules: tuple[str, ...],
    generations: int,
    bound: float,
    switch_seconds: float,
    key: jax.Array | None = None,
    population: np.ndarray | None = None,
) -> CodePM:
    """DE (the run's ``[de]``, checkpoint ``name``) of a program module with one camera input
    and one code neuron per tile kind of ``rules``, on the program reward without the robot
    (:func:`~mbn.experiments.program_module.code_fitness`): after a tile of kind k, code
    ``e_k``. Genes in ``[-bound, bound]``; ``key`` defaults to the stage's; ``population``:
    the first generation (default: drawn at random)."""
    kinds = len(rules)
    genome, fitness = code_pm_fitness(kinds, switch_seconds)
    run = ctx.evolve(
        name,
        de_config(ctx, genome.size, bound),
        fitness,
        ctx.key if key is None else key,
        generations,
        f"{kinds}-behaviour PM: DE",
        population,
    )
    pm = genome.network(jnp.asarray(run.data["best_genome"]))
    pm = jax.tree.map(lambda a: jnp.asarray(np.asarray(a, np.float64)), pm)
    codes = latched_codes(pm, kinds)
    latched = {r: None if c is None else c.tolist() for r, c in zip(rules, codes, strict=True)}
    return CodePM(pm, run, latched)


def code_pm_fitness(
    kinds: int, switch_seconds: float
) -> tuple[PMGenome, Callable[[jax.Array], jax.Array]]:
    """The genome of a code program module for ``kinds`` tile kinds and its program reward
    without the robot (:func:`~mbn.experiments.program_module.code_fitness`): after a tile of
    kind k, code ``e_k`` within ``switch_seconds``."""
    genome = PMGenome(programs=kinds, inputs=kinds)
    codes = {tuple(float(i == t) for i in range(kinds)): np.eye(kinds)[t] for t in range(kinds)}
    sequences = tile_sequences(kinds, MemoryReward())
    return genome, code_fitness(genome, sequences, codes, switch=switch_seconds)


def latched_codes(pm: CTRNN, kinds: int) -> list[np.ndarray | None]:
    """The code a program module latches after a tile of each kind, 1 to ``kinds`` (its first
    ``kinds`` neurons; None where it never settles)."""
    out: list[np.ndarray | None] = []
    for t in range(kinds):
        got = latch_after_tile(pm, t + 1, range(kinds), see=MemoryReward().see)
        out.append(None if got is None else np.asarray(got.program))
    return out


def code_mbn(
    im_spec: InterpreterControllerSpec,
    pm: CTRNN,
    rules: tuple[str, ...],
    programs: list[Any],
    camera: CameraConfig,
    metadata: dict[str, Any],
) -> MBNControllerSpec:
    """The MBN of a code program module (:func:`evolve_code_pm`): its readout's columns are
    ``programs`` (one per tile kind of ``rules``), and it starts in the state the PM latches
    after a one-colour tile (the first rule), where the PM latches one."""
    kinds = len(rules)
    readout = np.stack([np.asarray(p, np.float64) for p in programs], axis=1)
    latch = latch_after_tile(pm, 1, range(kinds), see=MemoryReward().see)
    initial = (
        PMInitial(rule=rules[0], potentials=tuple(latch.potentials)) if latch is not None else None
    )
    return MBNControllerSpec(
        interpreter_spec=im_spec,
        program_module=pm,
        program_neurons=tuple(range(kinds)),
        camera=camera,
        initial=initial,
        readout=readout.tolist(),
        tile_rules=rules,
        metadata=metadata,
    )


def choose_code_mbn(
    ctx: StageContext,
    stem: str,
    im_spec: InterpreterControllerSpec,
    rules: tuple[str, ...],
    camera: CameraConfig,
    meta: dict[str, Any],
    *,
    generations: int,
    bound: float,
    switch_seconds: float,
    first: Callable[[jax.Array], np.ndarray] | None = None,
    maze_generations: int = 0,
) -> tuple[list[dict[str, Any]], int]:
    """The MBN of a code program module for ``rules`` (their programs those of ``im_spec``),
    as a stage makes its final choice: with maze episodes up to ``[validation] attempts``
    program modules (checkpoints ``STEM_pm``, ``STEM_pm_attempt1``, ...; attempt ``a`` from the
    stage's key folded with ``ATTEMPT_KEY + a``), each MBN judged in the validation split of its
    tile family, stopping at the first that meets the target; else one. ``first``: a first
    generation from an attempt's key (default: random). ``maze_generations``: where an
    attempt's MBN misses the validation target, DE generations of its program module driving
    the robot in mazes of the tile family's train split, from its reward's last population
    (:func:`~mbn.experiments.stages.pm_mazes.evolve_in_mazes`, checkpoint ``NAME_mazes``), the
    better MBN by validation kept. Returns every try (``pm``: :class:`CodePM`, the reward's
    run, the network and codes of the kept genome; ``spec``; ``validation`` or None; ``maze``:
    :func:`~mbn.experiments.stages.pm_mazes.maze_record` with that MBN's ``validation`` and
    whether it was ``kept``, or None) and the index of the one kept: the best by
    :func:`~mbn.experiments.stages.common.validation_figure`, then by program reward."""
    programs = [im_spec.programs[r] for r in rules]
    attempts = ctx.section(ValidationSettings).attempts if maze_episodes(ctx) is not None else 1
    tries: list[dict[str, Any]] = []
    for a in range(attempts):
        key = ctx.key if a == 0 else jax.random.fold_in(ctx.key, ATTEMPT_KEY + a)
        name = f"{stem}_pm" if a == 0 else f"{stem}_pm_attempt{a}"
        population = None if first is None else first(key)
        pm = evolve_code_pm(ctx, name, rules, generations, bound, switch_seconds, key, population)
        spec = code_mbn(im_spec, pm.network, rules, programs, camera, meta)
        check = validate(ctx, spec, "tiles") if attempts > 1 or maze_generations else None
        maze = None
        if maze_generations and check is not None and not check["meets_target"]:
            # it misses its target: the PM's last generations drive the robot in mazes, from
            # the reward's population, and the better MBN by validation is kept
            genome = PMGenome(programs=len(rules), inputs=len(rules))

            def build(genes: Any, genome: PMGenome = genome) -> tuple[MBNControllerSpec, CTRNN]:
                net = genome.network(jnp.asarray(genes))
                net = jax.tree.map(lambda x: jnp.asarray(np.asarray(x, np.float64)), net)
                return code_mbn(im_spec, net, rules, programs, camera, meta), net

            maze, (driven, net) = mend_in_mazes(
                ctx,
                f"{name}_mazes",
                spec,
                check,
                genome,
                rules,
                np.asarray(pm.run.state.population),
                key,
                maze_generations,
                bound,
                f"{len(rules)}-behaviour PM: generations driving the robot in mazes",
                build,
            )
            if maze["kept"]:
                codes = latched_codes(net, len(rules))
                latched = {
                    r: None if c is None else c.tolist() for r, c in zip(rules, codes, strict=True)
                }
                pm, spec, check = CodePM(net, pm.run, latched), driven, maze["validation"]
        tries.append({"pm": pm, "spec": spec, "validation": check, "maze": maze})
        if check is None or check["meets_target"]:
            break
    chosen = max(
        range(len(tries)),
        key=lambda i: (
            validation_figure(tries[i]["validation"]) if tries[i]["validation"] else 0.0,
            tries[i]["pm"].run.data["best_fitness"],
            -i,
        ),
    )
    return tries, chosen


def attempts_record(tries: list[dict[str, Any]], chosen: int) -> dict[str, Any]:
    """What a stage records of :func:`choose_code_mbn`'s tries, where it made several: the kept
    one's validation, every attempt's reward and validation, and which was kept."""
    if tries[0]["validation"] is None:  # one attempt, not validated
        return {}
    return {
        "validation": tries[chosen]["validation"],
        "attempts": [
            {
                "best_fitness": t["pm"].run.data["best_fitness"],
                "validation": t["validation"],
                **(
                    {"maze_fitness": t["maze"]["best_fitness"], "maze_kept": t["maze"]["kept"]}
                    if t.get("maze")
                    else {}
                ),
            }
            for t in tries
        ],
        "chosen_attempt": chosen,
    }


@dataclass(frozen=True, kw_only=True)
class MBN3Result(Record):
    """What the ``mbn3`` stage records (``stages/mbn3.json``): the program module's DE run, the
    tile rules and the codes each latches, the initial rule, the interpreter's digest checked,
    and, when it made several attempts, the kept one's validation and every attempt; with
    ``[mbn3] maze_generations``, ``maze``: the kept attempt's generations driving the robot,
    run where its MBN missed the validation target (:func:`~mbn.experiments.stages.pm_mazes.
    maze_record`, with that MBN's ``validation`` and whether it was ``kept``: then its
    ``best_genome`` is the MBN's program module and ``latched_codes`` are its)."""

    best_genome: list[float]
    best_fitness: float
    generations: int
    history: History
    tile_rules: list[str]
    latched_codes: dict[str, Any]
    initial: str | None
    sha256: str
    sha256_checked: bool
    validation: Validation | None = optional()
    attempts: list[dict[str, Any]] | None = optional()
    chosen_attempt: int | None = optional()
    maze: dict[str, Any] | None = optional()


class MBN3Stage(Stage[MBN3Result]):
    name = "mbn3"
    key_id = KEYS["mbn3"]
    outputs = ("controllers/mbn3.json",)
    needs = ("im_full", "programs")
    settings = MBN3Settings

    result = MBN3Result

    def run(self, ctx: StageContext) -> MBN3Result:
        s: MBN3Settings = ctx.settings
        path = ctx.rundir.controller_file("im_full_programs")
        im_spec = read_controller_spec(path)
        if not isinstance(im_spec, InterpreterControllerSpec):
            raise MbnInputError(f"{path}: not an interpreter")
        digest = ctx.read(IMFullStage).sha256
        check_digest(im_spec.interpreter, digest, "mbn3")
        rules = tuple(parse_rule(r).name for r in s.tile_rules)
        missing = [r for r in rules if r not in im_spec.programs]
        if missing:
            raise MbnInputError(
                f"mbn3.tile_rules: {path} has no program for {', '.join(missing)} (it has "
                f"{', '.join(im_spec.programs)})"
            )
        meta = {"made_by": MADE_BY, "stage": self.name, "seed": ctx.seed, "sha256": digest}
        camera = CameraConfig(range=s.camera_range)
        # with maze episodes the final choice drives the robot: up to [validation] attempts
        # PMs, each judged in the tiles3 family's validation mazes, the best kept
        tries, chosen = choose_code_mbn(
            ctx,
            "mbn3",
            im_spec,
            rules,
            camera,
            meta,
            generations=s.generations,
            bound=s.bound,
            switch_seconds=s.switch_seconds,
            maze_generations=s.maze_generations,
        )
        pm, spec = tries[chosen]["pm"], tries[chosen]["spec"]
        run = pm.run
        save_controller(ctx.rundir.controller_file("mbn3"), spec)
        again = read_controller_spec(ctx.rundir.controller_file("mbn3"))
        assert isinstance(again, MBNControllerSpec)
        check_digest(again.interpreter_spec.interpreter, digest, "controllers/mbn3.json")
        return MBN3Result.from_json(
            {
                "best_genome": run.data["best_genome"],
                "best_fitness": run.data["best_fitness"],
                "generations": s.generations,
                "history": run.data["history"],
                "tile_rules": list(rules),
                "latched_codes": pm.latched,
                "initial": None if spec.initial is None else spec.initial.rule,
                "sha256": digest,
                "sha256_checked": True,
                **attempts_record(tries, chosen),
                **({"maze": tries[chosen]["maze"]} if tries[chosen]["maze"] else {}),
            }
        )

    def summary(self, result: MBN3Result) -> str:
        data = result.to_json()
        return (
            f"program reward {data['best_fitness']:.4f} after {data['generations']} generations; "
            f"tiles {', '.join(data['tile_rules'])}"
        )
