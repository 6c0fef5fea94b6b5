"""Stage ``contest``: programs against dynamics. For each new rule (straight-right and
straight-left by default), three contenders are evolved with the same DE (``[de]``: population,
F, CR), the same crossroad episodes and perturbed copies, and the same budget of evaluations:

* ``programs``: DE over the programs of the fixed fully programmable interpreter of ``im_full``
  (its sha256 checked before and after), each program scored as the network it encodes (as the
  ``programs`` stage of ``mbn run new-behaviours`` does);
* ``scratch``: a new 3-neuron CTRNN, the follower genome's 12 genes within the followers'
  bounds, from a random population (as RF is evolved);
* ``neighbour``: RF's network re-evolved on all its 12 genes, from a population around RF
  (RF itself and copies with Gaussian noise of ``[contest] neighbour_sigma``).

Every ``check_every`` generations (and at generation 0) the best genome so far is tested on the
three-tile test maze: every start mark once, and where every mark passes, the jittered starts.
A dynamics contender's best is tested as its network; program search's best program as the
fixed interpreter runs it, multipliers and all (``[contest] program_checks = "interpreter"``,
the default: what an MBN would do with it), or as the network it encodes (``"network"``, the
way runs recorded before the setting existed were checked).
It *succeeds* when every mark succeeds and at least ``[contest] jitter_target`` of the jittered
trials do; a run's evaluations to success are those DE had spent when it first did
(``popsize × (generation + 1)``), and a run that never did is censored at the budget. The check
measures; it never selects (DE sees only the crossroad fitness). A contender stops at its first
successful check (``[contest] stop_when_solved``; its evaluations to success are known then, and
its best then is its product); one that never succeeds runs the whole budget. At the end each
contender's
best is tested on the marks, the jittered starts and the held-out maze, and the programs'
through the interpreter itself too, multipliers and all (with its agreement).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from mbn.config import Settings, setting
from mbn.controllers import (
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    make_controller,
    read_controller_spec,
    save_controller,
    step_beyond_limit,
)
from mbn.errors import MbnInputError
from mbn.evolution.de import DEConfig
from mbn.experiments.evolve import Genome, crossroad_fitness, robust_fitness
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.pipeline.results import Record
from mbn.experiments.stages.common import (
    MADE_BY,
    de_config,
    read_network,
    rf_lf_programs,
    stage_perturbations,
    task,
)
from mbn.experiments.stages.im_full import IMFullStage
from mbn.experiments.stages.keys import KEYS
from mbn.experiments.stages.programs import (
    check_digest,
    program_de_config,
    program_fitness,
    program_network,
)
from mbn.experiments.stages.protocol import SUFFIXES
from mbn.experiments.stages.records import TestMazes
from mbn.experiments.stages.settings import DESettings, FollowerSettings
from mbn.experiments.stages.tests import TestsSettings
from mbn.experiments.stages.tests3 import Tests3Settings, trial_specs
from mbn.experiments.trials import (
    TrialGroup,
    agreement,
    run_loaded_trials,
    run_trial_groups,
    run_trials,
    summary,
)
from mbn.io import read_json, write_json_atomic
from mbn.networks.ctrnn import CTRNN
from mbn.world.mazes.load import load_maze
from mbn.world.rules import parse_rule, parse_rules

__all__ = [
    "CONTENDERS",
    "PROGRAM_CONTENDERS",
    "Contender",
    "ContestCheck",
    "ContestResult",
    "ContestRun",
    "ContestSettings",
    "ContestStage",
    "check",
    "contend",
    "final_tests",
    "k_interpreter",
    "neighbour_population",
    "program_controller",
]

#: The contenders, in the report's order, with a line each.
CONTENDERS: dict[str, str] = {
    "programs": "program search on the fixed fully programmable interpreter",
    "scratch": "dynamics from scratch: a new 3-neuron CTRNN (12 genes)",
    "neighbour": "dynamics from a neighbour: RF re-evolved on its 12 genes",
    "programs_k": "program search over only the k connections where LF differs from RF (the "
    "paper's k = 3), each over the same range as the fully programmable interpreter's",
}
#: The contenders that search programs (the others learn dynamics).
PROGRAM_CONTENDERS = ("programs", "programs_k")

#: What the record of a rule's start-mark trials keeps of each contender's trajectory.
TRAJECTORY_FIELDS = ("t", "pose", "stalled")

#: How program search's best so far can be checked (``[contest] program_checks``).
PROGRAM_CHECKS = ("interpreter", "network")
#: Folded into the stage key for the neighbour's first population.
NEIGHBOUR_KEY = 1000


@dataclass(frozen=True)
class ContestSettings(Settings):
    """Programs against dynamics: the rules, the contenders, their budget and the check."""

    section = "contest"
    # runs recorded before ``program_checks`` existed checked programs as their networks
    recorded_before: ClassVar[dict[str, Any]] = {"program_checks": "network"}
    rules: tuple[str, ...] = setting(
        ("straight-right", "straight-left"),
        doc="the new rules each contender learns",
        source="docs/contest.md",
    )
    contenders: tuple[str, ...] = setting(
        tuple(CONTENDERS),
        doc="the contenders: programs, scratch, neighbour, programs_k",
        source="docs/contest.md",
    )
    generations: int = setting(
        300,
        doc="DE generations of every contender (the budget: popsize x (generations + 1) "
        "evaluations)",
        low=0,
        high=100_000,
        source="as [programs] generations",
    )
    check_every: int = setting(
        10,
        doc="generations between two tests of the best so far (the resolution of evaluations "
        "to success)",
        low=1,
        high=100_000,
        source="docs/contest.md",
    )
    variants: int = setting(
        4, doc="starts per crossroad", low=1, high=100, source="as [rf] variants"
    )
    jitter_target: float = setting(
        0.95,
        doc="share of the jittered trials a check needs (with every start mark) to succeed",
        low=0.0,
        high=1.0,
        source="the paper's protocol and the issue's 95 %",
    )
    stop_when_solved: bool = setting(
        True,
        doc="stop a contender at its first successful check (its evaluations to success are "
        "known then; the final tests take that best); false: every contender runs its whole "
        "budget",
        source="docs/contest.md",
    )
    program_checks: str = setting(
        "interpreter",
        doc="how program search's best so far is checked: 'interpreter' (the fixed interpreter "
        "runs the program, multipliers and all: what an MBN would do with it) or 'network' "
        "(the network the program encodes, as its fitness scores it)",
        choices=PROGRAM_CHECKS,
        source="docs/contest.md (programs that passed as networks failed in the interpreter)",
    )
    neighbour_sigma: float = setting(
        2.0,
        doc="Gaussian spread of the neighbour's first population around RF's genes (RF itself "
        "is its first member)",
        low=0.0,
        high=100.0,
        source="docs/contest.md (a tenth of the followers' weight bound)",
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        names = parse_rules(self.rules, "contest.rules")
        if not names or len(set(names)) != len(names):
            raise MbnInputError("contest.rules: at least one rule, none listed twice")
        if not self.contenders or len(set(self.contenders)) != len(self.contenders):
            raise MbnInputError("contest.contenders: at least one, none listed twice")
        for c in self.contenders:
            if c not in CONTENDERS:
                raise MbnInputError(
                    f"contest.contenders: {c!r} is not one of {', '.join(CONTENDERS)}"
                )


@dataclass(frozen=True)
class Contender:
    """One DE of the contest: its config, fitness, first population, genes -> network, and
    genes -> the controller its checks run."""

    config: DEConfig
    fitness: Callable[[jax.Array], jax.Array]
    population: np.ndarray | None
    network: Callable[[Any], CTRNN]
    checked: Callable[[Any], Any]


def program_controller(spec: InterpreterControllerSpec, rule: str, genes: Any) -> Any:
    """The fixed interpreter running program search's ``genes`` (clipped to [0, 1]) for
    ``rule``, multipliers and all: what an MBN would do with the program."""
    program = np.clip(np.asarray(genes, float), 0.0, 1.0)
    im = dataclasses.replace(spec, programs={rule: program.tolist()})
    return make_controller(im, rule, where="contest programs")


def _contender(
    ctx: StageContext,
    name: str,
    rule: str,
    spec: InterpreterControllerSpec,
    rf: CTRNN,
    variants: int,
) -> Contender:
    s: ContestSettings = ctx.settings
    de = ctx.section(DESettings)
    bound = ctx.section(FollowerSettings).weight_bound
    interp = spec.interpreter

    def as_network(network: Callable[[Any], CTRNN]) -> Callable[[Any], Any]:
        return lambda genes: make_controller(
            CTRNNControllerSpec(net=network(genes), behavior=rule),
            None,
            where="contest",
            check_stability=False,
        )

    if name in PROGRAM_CONTENDERS:
        decoded = lambda genes: program_network(  # noqa: E731
            interp, rf, np.clip(np.asarray(genes), 0.0, 1.0)
        )

        return Contender(
            program_de_config(ctx, interp),
            program_fitness(ctx, interp, rf, rule, variants),
            None,
            decoded,
            (
                (lambda genes: program_controller(spec, rule, genes))
                if s.program_checks == "interpreter"
                else as_network(decoded)
            ),
        )
    genome = Genome() if name == "scratch" else Genome.around(rf, Genome().connections)
    fitness = robust_fitness(
        crossroad_fitness(genome, task(ctx, rule, variants)),
        stage_perturbations(ctx, genome.size),
    )
    population = None
    if name == "neighbour":
        population = neighbour_population(
            genome.genes_of(rf),
            jax.random.fold_in(ctx.key, NEIGHBOUR_KEY),
            de.popsize,
            s.neighbour_sigma,
            bound,
        )
    network = lambda genes: genome.network(jnp.asarray(genes))  # noqa: E731
    return Contender(
        de_config(ctx, genome.size, bound), fitness, population, network, as_network(network)
    )


def k_interpreter(
    ctx: StageContext, full: InterpreterControllerSpec, rf: CTRNN, lf: CTRNN
) -> InterpreterControllerSpec:
    """The ``programs_k`` contender's interpreter: RF's, built as the fully programmable one
    (``full``: its multiplier, time constants, step and simulation) with only the connections
    where LF differs from RF programmable, each over ``[im_full] bound`` as there; RF's and
    LF's programs."""
    from mbn.experiments.stages.im_full import IMFullSettings
    from mbn.networks.multiplier import load_multiplier
    from mbn.networks.programmable import Programmable, build_interpreter, differing_connections

    s = ctx.section(IMFullSettings)
    mul = load_multiplier(ctx.rundir.controller_file("multiplier"))
    conns = [p.connection for p in differing_connections(rf, lf, margin=0.0)]
    interp = build_interpreter(
        rf, [Programmable(c, -s.bound, s.bound) for c in conns], mul, tau_ratio=s.tau_ratio
    )
    return dataclasses.replace(
        full,
        interpreter=interp,
        programs=rf_lf_programs(interp, rf, lf),
        metadata={**full.metadata, "sha256": interp.digest()},
    )


def neighbour_population(
    genes: np.ndarray, key: jax.Array, popsize: int, sigma: float, bound: float
) -> np.ndarray:
    """The neighbour's first population: ``genes`` (RF's) first, then copies with Gaussian
    noise of ``sigma`` on every gene, clipped to ``[-bound, bound]``."""
    noise = np.array(jax.random.normal(key, (popsize, genes.size)), dtype=float)  # a copy
    noise[0] = 0.0
    return np.clip(genes[None] + sigma * noise, -bound, bound)


def check(ctx: StageContext, maze: Any, specs: dict[str, Any], loaded: Any) -> dict[str, Any]:
    """The best so far tested (``loaded``: a network, or the interpreter with a program): the
    start marks, and the jittered starts only where every mark passed (a check that fails a
    mark fails; its jittered count is not run)."""

    def trials(spec: Any) -> dict[str, Any]:
        verdicts, _, _, _ = run_trial_groups(
            [maze],
            [TrialGroup("trials", 0, spec, loaded.initial_state)],
            loaded.controller,
            seconds=spec.seconds,
            dt=loaded.dt,
            sensors=loaded.sensors,
            camera=loaded.camera,
            until_judged=True,
        )
        return summary(verdicts["trials"])

    marks = trials(specs[""])
    if marks["successes"] < marks["trials"]:
        return {"marks": [marks["successes"], marks["trials"]], "jitter": None, "success": False}
    jitter = trials(specs["_jitter"])
    ok = jitter["success_rate"] >= ctx.section(ContestSettings).jitter_target
    return {
        "marks": [marks["successes"], marks["trials"]],
        "jitter": [jitter["successes"], jitter["trials"]],
        "success": bool(ok),
    }


def final_tests(
    loaded: Any, maze: Any, heldout: Any, specs: dict[str, Any]
) -> tuple[dict[str, Any], Any, dict[str, Any]]:
    """A final best's tests (``loaded``: its controller): the start marks (its trajectories
    recorded for the report's pictures, every second step), the jittered starts and the
    held-out maze. Returns the verdicts by test suffix, the marks' trajectory and their
    per-trial details."""
    verdicts: dict[str, Any] = {}
    trajectory, details = None, {}
    for suffix in SUFFIXES:
        if suffix == "":
            got, ran, _ = run_trials(
                maze,
                specs[suffix],
                loaded.controller,
                loaded.initial_state,
                dt=loaded.dt,
                sensors=loaded.sensors,
                camera=loaded.camera,
                record_every=2,
            )
            trajectory = ran.trajectory
            details = {
                "success": got["success"].astype(int).tolist(),
                "correct": got["correct"].astype(int).tolist(),
                "judged": got["judged"].astype(int).tolist(),
                "stall": np.round(got["stall"].astype(float), 5).tolist(),
            }
        else:
            m = heldout if suffix == "_heldout" else maze
            got, _, _ = run_loaded_trials(m, specs[suffix], loaded)
        verdicts[suffix] = got
    return verdicts, trajectory, details


def contend(
    ctx: StageContext,
    name: str,
    description: str,
    c: Contender,
    key: jax.Array,
    test: Callable[[Any], dict[str, Any]],
) -> tuple[list[dict[str, Any]], Any]:
    """One contender's DE (checkpoint ``name``) with its best so far checked (``test`` of the
    controller ``c.checked`` makes of it) at generation 0 and every ``[contest] check_every``
    generations, each check logged atomically (``checkpoints/NAME.checks.json``) so that a run
    resumes to the same data; it stops at the first successful check where ``[contest]
    stop_when_solved``. Returns the checks and DE's final result."""
    s: ContestSettings = ctx.section(ContestSettings)
    popsize = c.config.popsize
    marks = sorted({0, *range(0, s.generations + 1, s.check_every), s.generations})
    log = ctx.rundir.checkpoint_file(name).with_suffix(".checks.json")
    checks: list[dict[str, Any]] = read_json(log) if log.exists() else []
    done = {int(x["generation"]) for x in checks}
    solved_at = next((int(x["generation"]) for x in checks if x["success"]), None)
    result = None
    for g in marks:
        if s.stop_when_solved and solved_at is not None:
            break
        if g in done:
            continue
        result = ctx.evolve(name, c.config, c.fitness, key, g, description, c.population)
        best = [float(x) for x in np.asarray(result.data["best_genome"])]
        last = checks[-1] if checks else None
        if last is not None and last["best_genome"] == best:
            verdict = {k: last[k] for k in ("marks", "jitter", "success")}
        else:
            verdict = test(c.checked(best))
        checks.append(
            {
                "generation": g,
                "evaluations": popsize * (g + 1),
                "best_fitness": float(result.data["best_fitness"]),
                "best_genome": best,
                **verdict,
            }
        )
        write_json_atomic(log, checks)
        if verdict["success"] and solved_at is None:
            solved_at = g
    if result is None:  # every check was done before: the final state
        stop = solved_at if s.stop_when_solved and solved_at is not None else None
        result = ctx.evolve(
            name,
            c.config,
            c.fitness,
            key,
            s.generations if stop is None else stop,
            description,
            c.population,
        )
    return checks, result


@dataclass(frozen=True, kw_only=True)
class ContestCheck(Record):
    """One check of a contender's best so far: the generation and evaluations spent, its
    fitness, its successes / trials on the start marks and the jittered starts (None: not run
    after the marks failed), and whether it passed."""

    generation: int
    evaluations: int
    best_fitness: float
    marks: list[int]
    jitter: list[int] | None
    success: bool


@dataclass(frozen=True, kw_only=True)
class ContestRun(Record):
    """What a report reads of one contender's run (``runs[rule][who]`` of ``stages/contest.json``
    and ``stages/contest3.json``; read with :meth:`~Record.pick`): solved or not, the
    evaluations it took (None: unsolved), its budget, final fitness, genes and checks, whether
    its final best passed, and, for program search, the program found and (the three-behaviour
    task) its program module's evaluations and reward."""

    solved: bool
    evaluations: int | None
    budget: int
    best_fitness: float
    checks: list[ContestCheck]
    genes: int
    final_success: bool
    program: list[float] | None = None
    pm_evaluations: int | None = None
    pm_fitness: float | None = None

    @property
    def evaluations_text(self) -> str:
        """``1200``, or ``> 4000 (unsolved)``."""
        return f"{self.evaluations}" if self.solved else f"> {self.budget} (unsolved)"


@dataclass(frozen=True, kw_only=True)
class ContestResult(Record):
    """What the ``contest`` stage records (``stages/contest.json``): by rule and contender, its
    run (solved, the evaluations it took, its checks, its network), the tests and agreements of
    what was found, the budget and population, the mazes, the interpreter's digest, the
    contenders and how programs were checked."""

    runs: dict[str, dict[str, Any]]
    tests: dict[str, Any]
    agreement: dict[str, Any]
    details: dict[str, Any]
    budget: int
    popsize: int
    check_every: int
    mazes: TestMazes
    sha256: str
    contenders: dict[str, str]
    program_checks: str


class ContestStage(Stage[ContestResult]):
    name = "contest"
    key_id = KEYS["contest"]
    needs = ("multiplier", "rf", "lf", "im_full")
    settings = ContestSettings

    result = ContestResult

    def run(self, ctx: StageContext) -> ContestResult:
        s: ContestSettings = ctx.settings
        spec = read_controller_spec(ctx.rundir.controller_file("im_full"))
        if not isinstance(spec, InterpreterControllerSpec):
            raise MbnInputError(f"{ctx.rundir.controller_file('im_full')}: not an interpreter")
        interp = spec.interpreter
        digest = ctx.read(IMFullStage).sha256
        check_digest(interp, digest, "contest")
        rf = read_network(ctx, "rf")
        specs_of = {"programs": spec}
        if "programs_k" in s.contenders:
            specs_of["programs_k"] = k_interpreter(ctx, spec, rf, read_network(ctx, "lf"))
        tests3 = ctx.section(Tests3Settings)
        maze, heldout = load_maze(tests3.maze), load_maze(tests3.heldout_maze)
        popsize = ctx.section(DESettings).popsize
        budget = popsize * (s.generations + 1)
        runs: dict[str, dict[str, Any]] = {}
        tests: dict[str, Any] = {}
        agree: dict[str, Any] = {}
        details: dict[str, Any] = {}
        for r, rule_text in enumerate(s.rules):
            rule = parse_rule(rule_text).name
            specs = trial_specs(rule, ctx.section(TestsSettings), ctx)
            runs[rule] = {}
            trajectories: dict[str, Any] = {}
            for c_index, who in enumerate(CONTENDERS):
                if who not in s.contenders:
                    continue
                c = _contender(ctx, who, rule, specs_of.get(who, spec), rf, s.variants)
                name = f"contest_{rule}_{who}"
                key = jax.random.fold_in(jax.random.fold_in(ctx.key, r), c_index)
                checks, result = contend(
                    ctx, name, f"{rule}: {who}", c, key, functools.partial(check, ctx, maze, specs)
                )
                hit = next((x for x in checks if x["success"]), None)
                net = c.network(result.data["best_genome"])
                final_spec = CTRNNControllerSpec(
                    net=net,
                    behavior=rule,
                    metadata={"made_by": MADE_BY, "stage": self.name, "seed": ctx.seed},
                )
                save_controller(ctx.rundir.controller_file(name), final_spec)
                # Tested as DE and the checks ran it: at the robot's network step, whether or
                # not that step is within the integrator's worst-case stability limit (a
                # network evolved on free genes may leave it; recorded below).
                plain = make_controller(final_spec, None, where=name, check_stability=False)
                short = f"{who}_{rule.replace('-', '_')}"
                verdicts, trajectories[who], details[short] = final_tests(
                    plain, maze, heldout, specs
                )
                for suffix, got in verdicts.items():
                    tests[f"{short}{suffix}"] = summary(got)
                record: dict[str, Any] = {
                    "solved": hit is not None,
                    "evaluations": None if hit is None else hit["evaluations"],
                    "generation": None if hit is None else hit["generation"],
                    "budget": budget,
                    "best_fitness": float(result.data["best_fitness"]),
                    "history": result.data["history"],
                    "checks": [{k: v for k, v in x.items() if k != "best_genome"} for x in checks],
                    "network": net.to_dict(),
                    "genes": len(checks[-1]["best_genome"]),
                    "step_beyond_stability_limit": step_beyond_limit(final_spec, name),
                    "final_success": bool(
                        tests[f"{short}"]["successes"] == tests[f"{short}"]["trials"]
                        and tests[f"{short}_jitter"]["success_rate"] >= s.jitter_target
                    ),
                }
                if who in PROGRAM_CONTENDERS:
                    program = np.clip(np.asarray(result.data["best_genome"], float), 0.0, 1.0)
                    emulated = program_controller(specs_of[who], rule, program)
                    for suffix in SUFFIXES:
                        m = heldout if suffix == "_heldout" else maze
                        got, _, _ = run_loaded_trials(m, specs[suffix], emulated)
                        tests[f"im_{short}{suffix}"] = summary(got)
                        agree[f"im_{short}{suffix}"] = agreement(got, verdicts[suffix])
                    record["program"] = program.tolist()
                runs[rule][who] = record
            ctx.rundir.save_trajectories(f"contest_{rule}", trajectories, TRAJECTORY_FIELDS)
            check_digest(interp, digest, f"contest ({rule})")
        return ContestResult.from_json(
            {
                "runs": runs,
                "tests": tests,
                "agreement": agree,
                "details": details,
                "budget": budget,
                "popsize": popsize,
                "check_every": s.check_every,
                "mazes": {"test": tests3.maze, "heldout": tests3.heldout_maze},
                "sha256": digest,
                "contenders": {k: CONTENDERS[k] for k in CONTENDERS if k in s.contenders},
                "program_checks": s.program_checks,
            }
        )

    def summary(self, result: ContestResult) -> str:
        parts = []
        for rule, by in result.runs.items():
            for who, d in by.items():
                e = ContestRun.pick(d, f"contest {rule} {who}").evaluations
                parts.append(f"{rule} {who}: " + (f"{e} evaluations" if e else "unsolved"))
        return "; ".join(parts)
