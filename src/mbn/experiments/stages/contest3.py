"""Stage ``contest3``: the three-behaviour task, an MBN against a monolithic CTRNN.

The task: a controller that follows the rule of the last tile it drove over, right after a
one-colour tile, left after a two-colour one, straight-right after a three-colour one
(``[contest3] tile_rules``). Two contenders, with the same DE (``[de]``), the same budget of
evaluations (``[contest] generations``) and the same checks as the ``contest`` stage's:

* ``programs``, the MBN's route (incremental): the interpreter of ``im_full`` stays fixed (its
  sha256 checked before and after), RF's and LF's programs are kept, and DE searches only the
  program of the new rule, on the crossroads with that rule's branch fitness (as the contest's
  program search); the MBN is that interpreter with a program module that latches one code per
  tile kind, evolved once without the robot (``[contest3] pm_generations``; its evaluations,
  robot-free, are reported apart) and whose readout's columns are the three programs;
* ``monolithic``: one CTRNN of ``[contest3] neurons`` neurons reading I1..I3 and the three tile
  kinds (:mod:`mbn.experiments.stages.monolithic`), evolved for the three rules at once.

Every ``[contest] check_every`` generations the best so far is run on the three-tile test maze
as the whole controller it stands for — the MBN with the candidate program; the monolithic
network — judged as ``tests3`` judges the three-behaviour MBN: by the rule of the last tile
driven over, and before the first tile by the first kind's rule, right (an MBN starts as RF; the
monolithic fitness scores the crossroads without a tile by it); a check succeeds with every
start mark and ``[contest] jitter_target`` of the jittered starts. Evaluations to success, stopping
and the final tests are the contest's (``docs/contest.md``). An evaluation of the monolithic
contender runs every rule's episodes, one of the program search its one rule's: the stage
records the robot episodes an evaluation costs each.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from mbn.config import Settings, setting
from mbn.controllers import (
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    MBNControllerSpec,
    SwitchedControllerSpec,
    make_controller,
    read_controller_spec,
    save_controller,
)
from mbn.controllers.spec import NUM_INPUTS
from mbn.errors import MbnInputError
from mbn.experiments.evolve import robust_fitness
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.pipeline.results import Record, optional
from mbn.experiments.program_module import MemoryReward
from mbn.experiments.stages.common import (
    MADE_BY,
    de_config,
    read_network,
    stage_perturbations,
    task,
)
from mbn.experiments.stages.contest import (
    TRAJECTORY_FIELDS,
    Contender,
    ContestSettings,
    check,
    contend,
    final_tests,
    neighbour_population,
)
from mbn.experiments.stages.im_full import IMFullStage
from mbn.experiments.stages.keys import KEYS
from mbn.experiments.stages.mbn3 import code_mbn, evolve_code_pm
from mbn.experiments.stages.monolithic import (
    MonolithicGenome,
    add_tile_kind,
    embed_rf,
    monolithic_fitness,
)
from mbn.experiments.stages.programs import (
    check_digest,
    program_de_config,
    program_fitness,
    program_network,
)
from mbn.experiments.stages.records import TestMazes
from mbn.experiments.stages.settings import DESettings, FollowerSettings
from mbn.experiments.stages.tests import TestsSettings
from mbn.experiments.stages.tests3 import Tests3Settings, trial_specs
from mbn.experiments.trials import summary
from mbn.world.engine import CameraConfig
from mbn.world.mazes.builtin import CROSSROAD_KINDS
from mbn.world.mazes.load import load_maze
from mbn.world.rules import parse_rule

__all__ = [
    "BASELINES3",
    "CONTENDERS3",
    "TASK",
    "Contest3Result",
    "Contest3Settings",
    "Contest3Stage",
]

#: The name of the three-behaviour task among the contest's rules (results, files, reports).
TASK = "three-behaviours"

#: The contenders of the three-behaviour task, with a line each.
CONTENDERS3: dict[str, str] = {
    "programs": "the MBN's route: program search for the new rule's program on the fixed "
    "interpreter, RF's and LF's programs kept, a code program module evolved without the robot",
    "monolithic": "one CTRNN reading the sonars and the three tile kinds, evolved for the three "
    "rules at once",
    "grown": "one CTRNN reading the sonars and the tile kinds, grown rule by rule as the MBN is "
    "(RF's network embedded, evolved for right and left with two tile inputs, then a third "
    "input and the three rules), at each size of [contest3] grown_neurons",
}


#: Folded into the stage's key for the MBN's program module (the number of contenders when
#: there were two: runs made since keep their program modules).
PM_KEY = 2

#: The baselines of the three-behaviour task: no search of their own, built from what the
#: programs contender found and tested as the contenders' finals are (``docs/contest.md``).
BASELINES3: dict[str, str] = {
    "oracle": "the switched-weights oracle: one 3-neuron CTRNN whose weights are swapped to the "
    "network each tile's program decodes to (the architecture's upper bound: what the "
    "multipliers and the program module cost)",
    "gate": "a gate among stored followers: the three decoded networks run side by side, the "
    "tile's one driving",
}


@dataclass(frozen=True)
class Contest3Settings(Settings):
    """The three-behaviour task: an MBN learning one program against a monolithic CTRNN."""

    section = "contest3"
    tile_rules: tuple[str, ...] = setting(
        ("right", "left", "straight-right"),
        doc="the rule a tile of 1, 2, 3 colours puts in force; the first two are RF's and LF's "
        "(im_full's programs right and left), the third the rule learned",
        source="docs/contest.md (the three-behaviour MBN of mbn run new-behaviours)",
    )
    contenders: tuple[str, ...] = setting(
        tuple(CONTENDERS3),
        doc="the contenders: programs, monolithic, grown",
        source="docs/contest.md",
    )
    neurons: int = setting(
        5,
        doc="neurons of the monolithic CTRNN (the followers' 3 and two to hold the rule)",
        low=3,
        high=20,
        source="docs/contest.md",
    )
    grown_neurons: tuple[int, ...] = setting(
        (5, 10),
        doc="the sizes of the grown contender (a run each: grown5, grown10, ...)",
        source="docs/contest.md (a monolithic network of one size could be too small)",
    )
    switches: bool = setting(
        True,
        doc="the monolithic fitness also scores each crossroad after another tile kind was "
        "shown (a rule it must give up), not only from rest",
        source="docs/contest.md (as the program module's reward)",
    )
    baselines: tuple[str, ...] = setting(
        tuple(BASELINES3),
        doc="the baselines built from the programs contender's programs and tested as the "
        "finals are: oracle, gate (needs the programs contender)",
        source="docs/contest.md",
    )
    pm_generations: int = setting(
        1500,
        doc="DE generations of the MBN's code program module (robot-free)",
        low=0,
        high=100_000,
        source="as [mbn3] generations",
    )
    pm_bound: float = setting(
        10.0, doc="the program module's genes are kept in [-bound, bound]", low=0.0, high=1e4
    )
    switch_seconds: float = setting(
        0.3,
        doc="how soon after a tile comes into view the PM's code must have switched",
        unit="s",
        low=0.0,
        high=10.0,
        source="as [mbn3] switch_seconds",
    )
    camera_range: float = setting(
        0.8,
        doc="the camera's range, for both contenders",
        unit="m",
        low=0.1,
        high=10.0,
        source="as [mbn3]",
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        try:
            names = [parse_rule(r).name for r in self.tile_rules]
        except MbnInputError as exc:
            raise MbnInputError(f"contest3.tile_rules: {exc}") from None
        if len(names) != 3 or len(set(names)) != 3:
            raise MbnInputError(
                f"contest3.tile_rules: three different rules, one per tile kind, got {names}"
            )
        if names[:2] != ["right", "left"]:
            raise MbnInputError(
                "contest3.tile_rules: the first two are RF's and LF's rules, right and left "
                f"(the programs the MBN keeps), got {names[:2]}"
            )
        if not self.contenders or len(set(self.contenders)) != len(self.contenders):
            raise MbnInputError("contest3.contenders: at least one, none listed twice")
        for c in self.contenders:
            if c not in CONTENDERS3:
                raise MbnInputError(
                    f"contest3.contenders: {c!r} is not one of {', '.join(CONTENDERS3)}"
                )
        for b in self.baselines:
            if b not in BASELINES3:
                raise MbnInputError(
                    f"contest3.baselines: {b!r} is not one of {', '.join(BASELINES3)}"
                )
        if any(not NUM_INPUTS <= n <= 20 for n in self.grown_neurons) or len(
            set(self.grown_neurons)
        ) != len(self.grown_neurons):
            raise MbnInputError(
                f"contest3.grown_neurons: distinct sizes of {NUM_INPUTS} to 20 neurons, got "
                f"{list(self.grown_neurons)}"
            )
        if len(set(self.baselines)) != len(self.baselines):
            raise MbnInputError("contest3.baselines: none listed twice")
        if self.baselines and "programs" not in self.contenders:
            raise MbnInputError(
                "contest3.baselines: built from the programs contender's programs, which is "
                "not among the contenders"
            )


@dataclass(frozen=True, kw_only=True)
class Contest3Result(Record):
    """What the ``contest3`` stage records (``stages/contest3.json``): the three-behaviour
    task's runs by contender, the tests of what was found, the budget and population, the tile
    rules and the new rule, the monolithic network's size, the episodes per evaluation, the
    mazes, the interpreter's digest and the contenders."""

    runs: dict[str, dict[str, Any]]
    tests: dict[str, Any]
    details: dict[str, Any]
    budget: int
    popsize: int
    check_every: int
    tile_rules: list[str]
    new_rule: str
    neurons: int
    episodes_per_evaluation: dict[str, Any]
    mazes: TestMazes
    sha256: str
    contenders: dict[str, str]
    baselines: dict[str, dict[str, Any]] | None = optional()


class Contest3Stage(Stage[Contest3Result]):
    name = "contest3"
    key_id = KEYS["contest3"]
    needs = ("rf", "im_full")
    settings = Contest3Settings

    result = Contest3Result

    def run(self, ctx: StageContext) -> Contest3Result:
        s: Contest3Settings = ctx.settings
        contest: ContestSettings = ctx.section(ContestSettings)
        path = ctx.rundir.controller_file("im_full")
        spec = read_controller_spec(path)
        if not isinstance(spec, InterpreterControllerSpec):
            raise MbnInputError(f"{path}: not an interpreter")
        interp = spec.interpreter
        digest = ctx.read(IMFullStage).sha256
        check_digest(interp, digest, "contest3")
        rf = read_network(ctx, "rf")
        rules = tuple(parse_rule(r).name for r in s.tile_rules)
        new_rule = rules[2]
        tests3 = ctx.section(Tests3Settings)
        maze, heldout = load_maze(tests3.maze), load_maze(tests3.heldout_maze)
        popsize = ctx.section(DESettings).popsize
        budget = popsize * (contest.generations + 1)
        camera = CameraConfig(range=s.camera_range)
        # judged as tests3 judges the three-behaviour MBN: before the first tile, the first
        # tile kind's rule (an MBN starts as RF)
        specs = trial_specs("tiles", ctx.section(TestsSettings), ctx, rules[0], rules)
        copies = 1 + ctx.section(FollowerSettings).perturbation_copies  # a genome and its copies
        meta = {"made_by": MADE_BY, "stage": self.name, "seed": ctx.seed}
        pm = None
        if "programs" in s.contenders:
            pm = evolve_code_pm(
                ctx,
                "contest3_pm",
                rules,
                s.pm_generations,
                s.pm_bound,
                s.switch_seconds,
                jax.random.fold_in(ctx.key, PM_KEY),
            )
        kept = [spec.programs[r] for r in rules[:2]]

        def mbn_of(genes: Any) -> MBNControllerSpec:
            assert pm is not None
            program = np.clip(np.asarray(genes, float), 0.0, 1.0).tolist()
            return code_mbn(
                spec, pm.network, rules, [*kept, program], camera, {**meta, "sha256": digest}
            )

        def monolithic_of(genome: MonolithicGenome, genes: Any) -> CTRNNControllerSpec:
            return CTRNNControllerSpec(
                net=genome.network(jnp.asarray(genes)),
                tile_rules=rules,
                camera=camera,
                metadata=meta,
            )

        bound = ctx.section(FollowerSettings).weight_bound
        marks = len(CROSSROAD_KINDS)

        def monolithic(genome: MonolithicGenome, population: np.ndarray | None) -> Contender:
            """DE of a monolithic network for the tile kinds of ``genome`` (the first rules)."""
            kinds = rules[: genome.kinds]
            tasks = [
                dataclasses.replace(task(ctx, r, contest.variants), tile=k + 1)
                for k, r in enumerate(kinds)
            ]
            return Contender(
                de_config(ctx, genome.size, bound),
                robust_fitness(
                    monolithic_fitness(
                        genome,
                        tasks,
                        camera,
                        see=MemoryReward().see,
                        hold=MemoryReward().hold,
                        switches=s.switches,
                        rest=task(ctx, rules[0], contest.variants),
                    ),
                    stage_perturbations(ctx, genome.size),
                ),
                population,
                lambda genes: genome.network(jnp.asarray(genes)),
                lambda genes: make_controller(
                    monolithic_of(genome, genes), None, where="contest3", check_stability=False
                ),
            )

        def episodes_of(kinds: int) -> int:
            per_rule = marks * contest.variants + (marks * (kinds - 1) * s.switches)
            return (kinds * per_rule + marks * contest.variants) * copies

        # each contender's runs: (name, key, the genome its genes are of)
        plan: list[tuple[str, str, jax.Array, MonolithicGenome | None]] = []
        for c_index, who in enumerate(CONTENDERS3):
            if who not in s.contenders:
                continue
            key = jax.random.fold_in(ctx.key, c_index)
            if who == "grown":
                for n in s.grown_neurons:
                    genome = MonolithicGenome(neurons=n, kinds=len(rules))
                    plan.append((who, f"grown{n}", jax.random.fold_in(key, n), genome))
            else:
                genome = MonolithicGenome(neurons=s.neurons, kinds=len(rules))
                plan.append((who, who, key, None if who == "programs" else genome))

        runs: dict[str, Any] = {}
        tests: dict[str, Any] = {}
        details: dict[str, Any] = {}
        trajectories: dict[str, Any] = {}
        episodes: dict[str, int] = {}
        for kind, who, key, genes_of in plan:
            grown: dict[str, Any] | None = None
            if kind == "programs":
                c = Contender(
                    program_de_config(ctx, interp),
                    program_fitness(ctx, interp, rf, new_rule, contest.variants),
                    None,
                    lambda genes: program_network(interp, rf, np.clip(np.asarray(genes), 0.0, 1.0)),
                    lambda genes: make_controller(mbn_of(genes), None, where="contest3 mbn"),
                )
                episodes[who] = len(CROSSROAD_KINDS) * contest.variants * copies
            elif kind == "grown":
                assert genes_of is not None
                c, grown = self._grown(ctx, who, key, genes_of, rf, monolithic, bound)
                episodes[who] = episodes_of(len(rules))
            else:
                assert genes_of is not None
                c = monolithic(genes_of, None)
                episodes[who] = episodes_of(len(rules))
            name = f"contest_{TASK}_{who}"
            checks, result = contend(
                ctx, name, f"{TASK}: {who}", c, key, functools.partial(check, ctx, maze, specs)
            )
            hit = next((x for x in checks if x["success"]), None)
            best = np.asarray(result.data["best_genome"])
            final = mbn_of(best) if genes_of is None else monolithic_of(genes_of, best)
            save_controller(ctx.rundir.controller_file(name), final)
            loaded = make_controller(final, None, where=name, check_stability=False)
            short = f"{who}_{TASK.replace('-', '_')}"
            verdicts, trajectories[who], details[short] = final_tests(loaded, maze, heldout, specs)
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
                "network": c.network(best).to_dict(),
                "genes": int(best.size),
                "episodes_per_evaluation": episodes[who],
                "final_success": bool(
                    tests[short]["successes"] == tests[short]["trials"]
                    and tests[f"{short}_jitter"]["success_rate"] >= contest.jitter_target
                ),
            }
            if grown is not None:
                record.update(grown)
            if who == "programs":
                assert pm is not None
                record["program"] = np.clip(best.astype(float), 0.0, 1.0).tolist()
                record["pm_evaluations"] = popsize * (s.pm_generations + 1)
                record["pm_fitness"] = float(pm.run.data["best_fitness"])
            runs[who] = record
        baselines: dict[str, dict[str, Any]] = {}
        if s.baselines and "programs" in runs:
            found = runs["programs"]["program"]
            nets = {
                r: program_network(interp, rf, np.asarray(p, float))
                for r, p in zip(rules, [*kept, found], strict=True)
            }
            for who in s.baselines:
                baseline = SwitchedControllerSpec(
                    networks=nets,
                    mode="swap" if who == "oracle" else "gate",
                    tile_rules=rules,
                    initial=rules[0],
                    camera=camera,
                    metadata={**meta, "baseline": who, "sha256": digest},
                )
                name = f"contest_{TASK}_{who}"
                save_controller(ctx.rundir.controller_file(name), baseline)
                loaded = make_controller(baseline, None, where=name, check_stability=False)
                short = f"{who}_{TASK.replace('-', '_')}"
                verdicts, trajectories[who], details[short] = final_tests(
                    loaded, maze, heldout, specs
                )
                for suffix, got in verdicts.items():
                    tests[f"{short}{suffix}"] = summary(got)
                baselines[who] = {
                    "what": BASELINES3[who],
                    "final_success": bool(
                        tests[short]["successes"] == tests[short]["trials"]
                        and tests[f"{short}_jitter"]["success_rate"] >= contest.jitter_target
                    ),
                }
        ctx.rundir.save_trajectories(f"contest_{TASK}", trajectories, TRAJECTORY_FIELDS)
        check_digest(interp, digest, "contest3 (after)")
        return Contest3Result.from_json(
            {
                "runs": {TASK: runs},
                "tests": tests,
                "details": details,
                "budget": budget,
                "popsize": popsize,
                "check_every": contest.check_every,
                "tile_rules": list(rules),
                "new_rule": new_rule,
                "neurons": s.neurons,
                "episodes_per_evaluation": episodes,
                "mazes": {"test": tests3.maze, "heldout": tests3.heldout_maze},
                "sha256": digest,
                "contenders": {k: CONTENDERS3[k] for k in CONTENDERS3 if k in s.contenders},
                "baselines": baselines or None,
            }
        )

    def _grown(
        self,
        ctx: StageContext,
        who: str,
        key: jax.Array,
        genome: MonolithicGenome,
        rf: Any,
        monolithic: Any,
        bound: float,
    ) -> tuple[Contender, dict[str, Any]]:
        """The grown contender of ``genome``'s size, grown as the MBN is: RF's network embedded
        (:func:`~mbn.experiments.stages.monolithic.embed_rf`, a first population around it as
        the neighbour's), evolved for the first two rules with two tile inputs (the contest's
        budget; checkpoint ``contest_three-behaviours_WHO_two``), then a third tile input
        added to every member (:func:`~mbn.experiments.stages.monolithic.add_tile_kind`): the
        contender whose DE the checks follow, as every other's. Returns it and what the run
        records of its first phase."""
        contest = ctx.section(ContestSettings)
        two = MonolithicGenome(neurons=genome.neurons, kinds=2)
        popsize = ctx.section(DESettings).popsize
        first = neighbour_population(
            embed_rf(two, rf), jax.random.fold_in(key, 1), popsize, contest.neighbour_sigma, bound
        )
        name = f"contest_{TASK}_{who}_two"
        phase = ctx.evolve(
            name,
            de_config(ctx, two.size, bound),
            monolithic(two, None).fitness,
            jax.random.fold_in(key, 2),
            contest.generations,
            f"{TASK}: {who}, right and left",
            first,
        )
        population = np.asarray(ctx.rundir.load_checkpoint(name).state.population, float)
        third = add_tile_kind(
            population, two, jax.random.fold_in(key, 3), contest.neighbour_sigma, bound
        )
        record = {
            "grown_from": "rf",
            "two_rule_evaluations": popsize * (contest.generations + 1),
            "two_rule_fitness": float(phase.data["best_fitness"]),
            "neurons": genome.neurons,
        }
        return monolithic(genome, third), record

    def summary(self, result: Contest3Result) -> str:
        data = result.to_json()
        parts = []
        for who, d in data["runs"][TASK].items():
            e = d["evaluations"]
            parts.append(f"{who}: " + (f"{e} evaluations" if e else "unsolved"))
        return f"{TASK}: " + "; ".join(parts)
