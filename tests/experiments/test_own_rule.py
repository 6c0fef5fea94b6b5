"""A rule and a fitness of your own, defined here, outside ``mbn``: registered, the rule is a rule
wherever one is named (the tasks, the judge, a family's checks), a tiny experiment's
``programs`` stage learns it with the registered fitness, and a bad registration is refused in
one line naming what is wrong (``register_rule``, ``register_fitness``)."""

from __future__ import annotations

import json
import re
from typing import Any

import jax.numpy as jnp
import numpy as np
import pytest

from mbn.controllers import (
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    read_controller_spec,
    save_controller,
)
from mbn.errors import MbnInputError
from mbn.experiments import crossroads, maze_task
from mbn.experiments.crossroads import CrossroadTask, rule_arm
from mbn.experiments.maze_task import MazeTask
from mbn.experiments.pipeline import Experiment, Registry, Stage, StageContext, run_experiment
from mbn.experiments.stages import tests as tests_stage
from mbn.experiments.stages.common import rf_lf_programs
from mbn.experiments.stages.im_full import IMFullResult
from mbn.experiments.stages.programs import ProgramsSettings, ProgramsStage
from mbn.experiments.stages.settings import (
    DESettings,
    FollowerSettings,
    ValidationSettings,
    derived_seeds,
)
from mbn.experiments.trials import TrialSpec
from mbn.networks.multiplier import load_default
from mbn.networks.programmable import build_interpreter, differing_connections
from mbn.notation import connection_name
from mbn.paper import published_lf, published_rf
from mbn.world.junctions import route_passes
from mbn.world.mazes.load import load_maze
from mbn.world.rules import (
    OPEN_BITS,
    open_mask,
    parse_rule,
    register_rule,
    rule_exit_codes,
    rule_names,
)
from tests.registries import isolate


def odd_one_out(open_exits: frozenset[str]) -> str:
    """Straight at a plus crossing, else the turn a T junction has alone, else right; back at a
    corner: no priority order does this."""
    if open_exits == {"right", "straight", "left"}:
        return "straight"
    if open_exits == {"right", "left"}:
        return "left"
    if "straight" in open_exits and len(open_exits) == 2:
        return next(iter(open_exits - {"straight"}))
    return "back"


@pytest.fixture
def own(monkeypatch):
    """The test's registrations stay in the test."""
    isolate(monkeypatch)


def _openings() -> list[frozenset[str]]:
    exits = ("right", "straight", "left")
    return [frozenset(e for k, e in enumerate(exits) if i >> k & 1) for i in range(8)]


def test_an_own_rule_is_a_rule_wherever_one_is_named(own):
    with pytest.raises(MbnInputError, match=r"^unknown rule 'odd-one-out': a name \(right, "):
        parse_rule("odd-one-out")
    rule = register_rule("odd-one-out", odd_one_out)
    assert parse_rule("Odd-One-Out") is rule and rule.name == "odd-one-out"
    assert rule_names()[-1] == "odd-one-out"
    assert register_rule("odd-one-out", odd_one_out) is rule  # a module imported twice
    # its exit for every set of open exits: the function's at a junction; straight along a
    # corridor, back at a dead end
    for opened in _openings():
        want = {frozenset(): "back", frozenset({"straight"}): "straight"}.get(opened)
        assert rule.exit(opened) == (want or odd_one_out(opened)), opened
    # the codes a compiled fitness and the judge read agree with it (NumPy and JAX)
    masks = np.array(
        [-1, *(open_mask(o) for o in _openings()), *(open_mask(o) | 1 for o in _openings())]
    )
    codes = {"back": 0, "right": 1, "straight": 2, "left": 3}
    want = [-1, *(codes[rule.exit(o)] for o in _openings() * 2)]
    assert rule_exit_codes("odd-one-out", masks).tolist() == want
    assert np.asarray(rule_exit_codes("odd-one-out", jnp.asarray(masks))).tolist() == want
    assert OPEN_BITS["back"] == 1  # the bit a table leaves out
    # the crossroads' arms (back: the south arm it came by), the tasks, the judge
    assert [rule_arm(k, "odd-one-out") for k in ("L", "S", "R", "LS", "LR", "SR", "LSR")] == [
        "B", "S", "B", "L", "L", "R", "S",
    ]  # fmt: skip
    assert CrossroadTask(rule="odd-one-out").fitness == "branch"
    assert MazeTask(rule="odd-one-out", pool=4, mazes=2).fitness == "junctions"
    assert TrialSpec(behavior="odd-one-out").behavior == "odd-one-out"
    assert ProgramsSettings(rules=("odd-one-out",)).rules == ("odd-one-out",)
    # the judge's walk through a maze takes its exits
    maze = load_maze("fig4")
    passes = route_passes(maze, tuple(maze.starts[0]), "odd-one-out", 3)
    assert passes is not None and len(passes) == 3
    assert all(p.rule == "odd-one-out" for p in passes)


def test_a_bad_rule_is_refused_in_one_line(own):
    register_rule("odd-one-out", odd_one_out)
    for call, pattern in [
        (
            lambda: register_rule("odd-one-out", lambda o: "back"),
            r"register_rule\('odd-one-out'\): a rule of that name is registered already",
        ),
        (
            lambda: register_rule("Odd One", odd_one_out),
            r"register_rule\('Odd One'\): a rule's name is lower-case words joined by '-'",
        ),
        (
            lambda: register_rule("right", lambda o: "back"),
            r"register_rule\('right'\): 'right' names a rule of mbn's already",
        ),
        (
            lambda: register_rule("lrs", lambda o: "back"),
            r"register_rule\('lrs'\): 'lrs' names a rule of mbn's already",
        ),
        (
            lambda: register_rule("tiles", lambda o: "back"),
            r"register_rule\('tiles'\): 'tiles' names a rule of mbn's already",
        ),
        (
            lambda: register_rule("sideways", lambda o: "straight"),
            r"register_rule\('sideways'\): with right open, exits gave 'straight': an open exit",
        ),
        (
            lambda: register_rule(
                "turner", lambda o: next(e for e in ("right", "left", "straight") if e in o)
            ),
            r"register_rule\('turner'\): it takes the exits of the rule 'right-left' at every "
            r"junction \(name that one\)",
        ),
        (
            lambda: register_rule("odd-again", odd_one_out),
            r"register_rule\('odd-again'\): it takes the exits of the rule 'odd-one-out'",
        ),
        (
            lambda: register_rule("broken", lambda o: o["right"]),
            r"register_rule\('broken'\): exits\(\{'right'\}\) failed: TypeError",
        ),
        (lambda: register_rule("nothing", "back"), r"exits must be a function of the open exits"),
    ]:
        with pytest.raises(MbnInputError) as caught:
            call()
        message = str(caught.value)
        assert "\n" not in message and re.search(pattern, message), message


def _units(stats: Any, arrays: Any, task: Any) -> Any:
    """1 an episode, whatever it did: a fitness the stage's records show it ran."""
    return jnp.ones_like(stats.stall_fraction)


def test_a_fitness_of_your_own_is_a_tasks_or_its_rules(own):
    register_rule("odd-one-out", odd_one_out)
    crossroads.register_fitness("units", _units, rules=("odd-one-out",))
    assert CrossroadTask(rule="odd-one-out").fitness == "units"  # the rule's own
    assert CrossroadTask(rule="right").fitness == "branch"
    assert CrossroadTask(rule="right", fitness="units").fitness == "units"  # named by a task
    maze_task.register_fitness(
        "maze-units", lambda stats, task: _units(stats, None, task), rules=("odd-one-out",)
    )
    assert MazeTask(rule="odd-one-out", pool=4, mazes=2).fitness == "maze-units"
    assert MazeTask(rule="right", pool=4, mazes=2).fitness == "junctions"
    for call, pattern in [
        (
            lambda: crossroads.register_fitness("units", lambda s, a, t: s.stall_fraction),
            r"register_fitness\('units'\): a fitness of that name is registered already",
        ),
        (
            lambda: crossroads.register_fitness("branch", _units),
            r"register_fitness\('branch'\): a fitness of that name is registered already",
        ),
        (
            lambda: crossroads.register_fitness("other", _units, rules=("odd-one-out",)),
            r"register_fitness\('other'\): the rule 'odd-one-out' has the fitness 'units' "
            "already",
        ),
        (
            lambda: crossroads.register_fitness("Other", _units),
            r"register_fitness\('Other'\): a fitness's name is lower-case words joined by '-'",
        ),
        (
            lambda: crossroads.register_fitness("other", _units, rules=("sideways",)),
            r"register_fitness\('other'\): rules: unknown rule 'sideways'",
        ),
        (
            lambda: maze_task.register_fitness("other", 3),
            r"register_fitness\('other'\): the fitness must be a function \(stats, task\)",
        ),
        (
            lambda: CrossroadTask(rule="right", fitness="nowhere"),
            r"fitness must be one of branch, paper, units, got 'nowhere'",
        ),
    ]:
        with pytest.raises(MbnInputError) as caught:
            call()
        message = str(caught.value)
        assert "\n" not in message and re.search(pattern, message), message


# --- a tiny experiment of your own that learns the rule ---------------------------------------


class PublishedRF(Stage):
    """The paper's published RF (no evolution), as the ``rf`` stage saves it."""

    name = "rf"
    key_id = 100
    outputs = ("controllers/rf.json",)

    def run(self, ctx: StageContext) -> dict[str, Any]:
        save_controller(ctx.rundir.controller_file("rf"), CTRNNControllerSpec(net=published_rf()))
        return {}


class SmallInterpreter(Stage[IMFullResult]):
    """The interpreter of the published RF, programmable where RF and LF differ (the paper's),
    as the ``im_full`` stage saves one, with the record the library's stages read of it (the
    ``programs`` stage checks its sha256)."""

    name = "im_full"
    key_id = 101
    needs = ("rf",)
    outputs = ("controllers/im_full.json",)
    result = IMFullResult

    def run(self, ctx: StageContext) -> IMFullResult:
        rf, lf = published_rf(), published_lf()
        conns = differing_connections(rf, lf, margin=0.0)
        interp = build_interpreter(rf, conns, load_default(3), tau_ratio=0.1)
        programs = rf_lf_programs(interp, rf, lf)
        spec = InterpreterControllerSpec(interpreter=interp, programs=programs, substeps=20)
        save_controller(ctx.rundir.controller_file("im_full"), spec)
        return IMFullResult(
            connections=[str(c) for c in interp.connections],
            connections_paper_notation=[connection_name(c) for c in interp.connections],
            bound=float(np.max(np.abs(interp.upper))),
            neurons=int(interp.num_neurons),
            multiplier_neurons=int(interp.mul_size),
            tau_ratio=0.1,
            multiplier_tau=0.1 * float(np.asarray(rf.tau).reshape(-1)[0]),
            substeps=20,
            step=0.1 / 20,
            sha256=interp.digest(),
            programs={r: list(p) for r, p in programs.items()},
            tests={},
            agreement={},
            curve=[],
            largest_set_meeting_targets=None,
        )


def tiny_experiment() -> Experiment:
    """The ``programs`` stage of the library learning ``odd-one-out`` on the fixed interpreter,
    with as little search and validation as it runs with."""
    return Experiment(
        name="odd-one-out",
        kind="lab.odd-one-out",
        registry=Registry([PublishedRF(), SmallInterpreter(), ProgramsStage()]),
        shared=(DESettings, FollowerSettings, ValidationSettings, tests_stage.TestsSettings),
        defaults={
            "programs": {
                "rules": ("odd-one-out",),
                "generations": 1,
                "variants": 1,
                "members": 0,
                "validation_mazes": (),
            },
            "de": {"popsize": 4},
            "followers": {"perturbation_copies": 0, "episode_seconds": 4.0},
            "validation": {"extra_mazes": (), "jitter_per_mark": 1, "attempts": 1},
            "tests": {"seconds": 4.0},
        },
        seeds=derived_seeds,
    )


# slow: a second path; CI checks the rule, its fitness and the family registered from outside
@pytest.mark.slow
def test_a_tiny_experiment_learns_an_own_rule_with_its_own_fitness(own, tmp_path):
    register_rule("odd-one-out", odd_one_out)
    crossroads.register_fitness("units", _units, rules=("odd-one-out",))
    experiment = tiny_experiment()
    config = experiment.config()
    assert config["programs"].rules == ("odd-one-out",)
    results = run_experiment(
        experiment, tmp_path / "run", seed=5, config=config, log=lambda _: None
    )
    found = results["stages"]["programs"]["rules"]["odd-one-out"]
    # trained with the rule's own fitness: 1 an episode, the seven crossroads once each
    assert found["best_fitness"] == pytest.approx(7.0)
    assert found["validation_im"]["trials"] > 0
    spec = read_controller_spec(tmp_path / "run" / "controllers" / "im_full_programs.json")
    assert set(spec.programs) == {"right", "left", "odd-one-out"}
    assert np.asarray(spec.programs["odd-one-out"]).shape == (len(spec.interpreter.connections),)
    assert json.loads((tmp_path / "run" / "results.json").read_text())["config"]["programs"][
        "rules"
    ] == ["odd-one-out"]
