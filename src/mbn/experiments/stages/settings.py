"""Settings of ``mbn reproduce`` shared by several stages, the quick preset and the derived seeds.

Each stage's own settings live beside it (``stages/NAME.py``). Defaults are the paper's where it
gives a value, else the documented deviation (``docs/reproduce.md``, "Deviations").
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from mbn.config import Locator, Settings, setting
from mbn.controllers.spec import MAX_SUBSTEPS
from mbn.errors import MbnInputError
from mbn.evolution.de import DEConfig
from mbn.experiments.crossroads import EPISODE_SECONDS
from mbn.experiments.named import (
    PAPER_TILE_RULES,
    check_not_test_mazes,
    locate,
    mbn_tile_rules,
    trial_maze,
)
from mbn.world.mazes.builtin import APPROACHES, check_approaches

__all__ = [
    "QUICK",
    "DESettings",
    "EpisodeSettings",
    "FollowerSettings",
    "InterpreterSettings",
    "LFSettings",
    "TestsSettings",
    "ValidationSettings",
    "derived_seeds",
]

_DE = {f.name: f.default for f in dataclasses.fields(DEConfig)}


@dataclass(frozen=True)
class DESettings(Settings):
    """Differential Evolution, DE/best/1/bin, for every evolved stage (RF, LF, PM)."""

    section = "de"
    popsize: int = setting(
        _DE["popsize"],
        doc="population size",
        low=4,
        high=10_000,
        source="paper 3.1 (18 individuals)",
    )
    F: float = setting(
        _DE["F"], doc="differential weight", low=0.0, high=2.0, source="paper 3.1 (step-size)"
    )
    CR: float = setting(
        _DE["CR"], doc="crossover probability", low=0.0, high=1.0, source="paper 3.1"
    )


@dataclass(frozen=True)
class FollowerSettings(Settings):
    """The wall followers' evolution (RF, the LF search and LF) on the crossroads."""

    section = "followers"
    weight_bound: float = setting(
        20.0,
        doc="genes are kept in [-bound, bound]",
        low=0.0,
        high=1e4,
        source="docs/reproduce.md (the paper's weights of hundreds make the Euler step unstable)",
    )
    perturbation_sigma: float = setting(
        0.3,
        doc="standard deviation of the fixed weight perturbations the fitness averages over",
        low=0.0,
        source="docs/reproduce.md (robust evolution)",
    )
    perturbation_copies: int = setting(
        3,
        doc="perturbed copies of each genome scored beside it (0: none)",
        low=0,
        high=100,
        source="docs/reproduce.md (robust evolution)",
    )
    episode_seconds: float = setting(
        EPISODE_SECONDS,
        doc="length of a training episode",
        unit="s",
        low=0.1,
        high=3600.0,
        source="paper 3.1 ('about 20 seconds'); docs/experiments.md",
    )


def family_names() -> tuple[str, ...]:
    """The registered maze families (:func:`mbn.world.mazes.families.register_family`): the
    choices of ``[episodes] family``."""
    from mbn.world.mazes.families import FAMILIES

    return tuple(FAMILIES)


@dataclass(frozen=True)
class EpisodeSettings(Settings):
    """Where the followers' training episodes come from (RF, the LF search and LF): the paper's
    seven crossroads, or mazes drawn from a family's train split and drawn again every
    ``redraw`` generations (``docs/generalization.md``, "Selection across the family")."""

    section = "episodes"
    # runs recorded before this section existed were evolved on the crossroads
    # (and maze runs recorded before ``search_starts`` searched on every start of a draw: 4)
    recorded_before: ClassVar[dict[str, Any]] = {"kind": "crossroads", "search_starts": 4}
    kind: str = setting(
        "maze",
        doc="maze: episodes drawn from a maze family's train split (docs/generalization.md); "
        "crossroads: the paper's seven crossroads (docs/configs/paper.toml)",
        choices=("crossroads", "maze"),
        source="paper 3.1; docs/generalization.md",
    )
    family: str = setting(
        "grid",
        doc="the maze family of maze episodes",
        choices=family_names,
        source="docs/generalization.md",
    )
    pool: int = setting(
        256,
        doc="training mazes drawn from the family's train split (once, by the run's seed)",
        low=1,
        high=100_000,
        source="docs/generalization.md",
    )
    mazes: int = setting(
        4,
        doc="mazes of the pool in one draw of episodes",
        low=1,
        high=10_000,
        source="docs/generalization.md",
    )
    starts: int = setting(
        4,
        doc="start marks of each maze in one draw (jittered)",
        low=1,
        high=10,
        source="docs/generalization.md",
    )
    search_starts: int = setting(
        2,
        doc="start marks of each maze in one draw of the LF search (as the crossroads' search "
        "runs 2 starts per crossroad where RF and LF run 4)",
        low=1,
        high=10,
        source="docs/generalization.md (cost)",
    )
    seconds: float = setting(
        60.0,
        doc="length of a maze episode",
        unit="s",
        low=1.0,
        high=3600.0,
        source="docs/generalization.md (three junctions of a generated maze at 0.3 m/s)",
    )
    redraw: int = setting(
        10,
        doc="generations between two draws of episodes (0: never, one draw for the whole run)",
        low=0,
        high=100_000,
        source="docs/generalization.md (the N measurement)",
    )
    stall_weight: float = setting(
        1.0,
        doc="weight of the stall fraction in the maze episodes' fitness",
        low=0.0,
        high=1000.0,
        source="docs/generalization.md (1: as the crossroads' branch fitness)",
    )


#: The interpreter's multipliers at tau / 40, integrated at h = tau_m / 10 (80 steps of a 0.1 s
#: robot step), as the fully programmable interpreter of ``mbn run new-behaviours`` runs them
#: (docs/reproduce.md, Deviations; docs/behaviours.md).
INTERPRETER_TAU_RATIO = 0.025
INTERPRETER_SUBSTEPS = 80


@dataclass(frozen=True)
class InterpreterSettings(Settings):
    """How the interpreter of RF and LF (stage ``im``, and the LF stage's check of every
    candidate) runs its multipliers: their time constant and the integration step."""

    section = "interpreter"
    # runs recorded before this section ran the paper's tau/10 at 20 steps
    recorded_before: ClassVar[dict[str, Any]] = {"tau_ratio": 0.1, "substeps": 20}
    tau_ratio: float = setting(
        INTERPRETER_TAU_RATIO,
        doc="the multipliers' time constant over the receiving neuron's (paper: an order of "
        "magnitude smaller, 0.1; here 0.025: their lag moves the networks off their branches)",
        low=1e-4,
        high=1.0,
        source="paper section 2; docs/reproduce.md (Deviations: the multipliers' lag)",
    )
    substeps: int = setting(
        INTERPRETER_SUBSTEPS,
        doc="interpreter steps per 0.1 s robot step (keep h / tau_m = 0.1, the multipliers' "
        "training step: 20 at tau/10, 80 at tau/40)",
        low=1,
        high=MAX_SUBSTEPS,
        source="docs/programmable.md",
    )


@dataclass(frozen=True)
class ValidationSettings(Settings):
    """How a stage checks its product before the next stage builds on it: success on the
    ``validation`` and ``validation2`` mazes, which no test uses, from jittered starts; a stage
    whose candidate falls short evolves another (``attempts`` in all) and keeps the best
    (docs/reproduce.md)."""

    section = "validation"
    # runs recorded before ``extra_mazes`` existed checked their candidates in ``maze`` alone
    recorded_before: ClassVar[dict[str, Any]] = {
        "extra_mazes": (),
        "split_mazes": 20,
        "split_jitter_per_mark": 2,
        "maze_share": 0.9,
    }
    maze: str = setting(
        "validation",
        doc="maze the candidates are checked in (built-in name or file; not a test maze)",
        source="docs/mazes.md",
    )
    extra_mazes: tuple[str, ...] = setting(
        ("validation2",),
        doc="more mazes the candidates are checked in, beside maze (none a test maze): the "
        "trials of every maze are pooled",
        source="docs/reproduce.md (Validation in two mazes)",
    )
    jitter_per_mark: int = setting(
        40,
        doc="starts per start mark and maze (the mark itself and jittered ones)",
        low=1,
        high=1000,
        source="docs/reproduce.md (Validation in two mazes)",
    )
    target: float = setting(
        0.95,
        doc="success rate a candidate must reach (the tests' target)",
        low=0.0,
        high=1.0,
        source="the per-run targets (docs/sweep.md)",
    )
    agreement: float = setting(
        0.99,
        doc="share of the validation trials in which the interpreter must take the exits the "
        "network it runs the program of takes (the tests ask 98 % of 200; at 0.99, 634 of the "
        "640 trials of the two mazes must agree)",
        low=0.0,
        high=1.0,
        source="docs/reproduce.md (Validation: which agreement holds in the tests)",
    )
    split_mazes: int = setting(
        100,
        doc="with maze episodes ([episodes] kind = maze): the candidates are checked in the "
        "first N mazes of the validation split of their family (the followers' and the "
        "programs': [episodes] family; an MBN's: the family of its tile kinds, tiles2 or "
        "tiles3), instead of maze and extra_mazes (100: the whole split, as many mazes as the "
        "test split judges)",
        low=1,
        high=100,
        source="docs/generalization.md (Validation on the validation split: the test's criterion)",
    )
    split_jitter_per_mark: int = setting(
        1,
        doc="with maze episodes: starts per start mark of each validation maze (the mark, then "
        "jittered ones; 1: each mark once, the test split's trials, so a maze reaches target "
        "as a test maze does)",
        low=1,
        high=1000,
        source="docs/generalization.md (Validation on the validation split: the test's criterion)",
    )
    maze_share: float = setting(
        0.9,
        doc="with maze episodes: share of the validation mazes that must each reach target "
        "(beside the pooled rate: the tests' second target)",
        low=0.0,
        high=1.0,
        source="the generalization targets (docs/generalization.md)",
    )
    attempts: int = setting(
        3,
        doc="candidates a stage evolves at most before it keeps the best",
        low=1,
        high=20,
        source="docs/reproduce.md",
    )

    def check_names(self, sections: Mapping[str, Settings], where: Locator) -> None:
        # each maze read and runnable (with the paper's tiles where the MBN is validated in
        # it: the pm stage), and none of them a test maze
        rules = PAPER_TILE_RULES if "pm" in sections else None
        names = [(locate(where, self.section, "maze"), self.maze)]
        names += [
            (locate(where, self.section, "extra_mazes", k), name)
            for k, name in enumerate(self.extra_mazes)
        ]
        for at, name in names:
            trial_maze(name, at, rules)
        check_not_test_mazes(names, sections)


#: The quick preset (``--quick``): a smoke run of every stage and output with tiny budgets.
QUICK: dict[str, dict[str, Any]] = {
    "followers": {"perturbation_copies": 1},
    "rf": {"generations": 15, "variants": 1, "restarts": 2},
    "lf_search": {"generations": 2, "variants": 1},
    "lf": {"generations": 20, "variants": 1, "finalists": 1, "rounds": 1},
    # no generations driving the robot (a test runs them on the quick run)
    "pm": {"generations": 30, "variants": 1, "maze_generations": 0},
    "tests": {"jitter_per_mark": 2, "heldout_repeats": 2},
    "validation": {
        "jitter_per_mark": 1,
        "attempts": 1,
        "split_mazes": 2,
        "split_jitter_per_mark": 1,
    },
    "episodes": {"pool": 16, "mazes": 2, "starts": 2, "search_starts": 1},
    # no worst-maze rerun: a compilation per controller kind saved (its picture: a test of its own)
    # one batch: a quick run's judging is compilation more than steps (a batch more per
    # controller kind cost it about 18 s cold)
    "generalization": {
        "test_mazes": 5,
        "gap_mazes": 3,
        "worst_maze": False,
        "zero_shot_batch": False,
    },
}


def derived_seeds(seed: int) -> dict[str, int]:
    """The seeds of the NumPy edges (jittered starts), derived from the run's seed."""
    return {
        "seed": seed,
        "crossroad_jitter": seed,
        "test_jitter": seed + 1,
        "heldout_jitter": seed + 2,
        "pm_crossroad_jitter": seed + 3,
        "validation_jitter": seed + 4,
    }


@dataclass(frozen=True)
class LFSettings(Settings):
    """The left-follower (LF): 3 connections of RF re-evolved."""

    section = "lf"
    # runs recorded before ``enough`` existed evolved every finalist of a round
    recorded_before: ClassVar[dict[str, Any]] = {"enough": 1.0}
    generations: int = setting(
        35,
        doc="DE generations of each finalist",
        low=0,
        high=100_000,
        source="docs/generalization.md (on maze episodes a finalist starts level: the LF "
        "search's population); the paper's protocol: 70 (docs/configs/paper.toml; a "
        "finalist's fitness levels off within about 60 there, docs/reproduce.md)",
    )
    finalists: int = setting(
        3,
        doc="the search's best triples re-evolved in each round; the best validated is kept",
        low=1,
        high=20,
        source="docs/reproduce.md (LF's quality is set by the triple's basin, not by length)",
    )
    rounds: int = setting(
        4,
        doc="rounds of finalists at most: the kept RF's, the rf stage's other RF's, then a fresh "
        "RF's each",
        low=1,
        high=20,
        source="docs/reproduce.md (about half the RFs make no left-follower three connections "
        "away)",
    )
    members: int = setting(
        3,
        doc="of each finalist's final population, validated alone, the best this many by that "
        "validation are checked as the interpreter's program; the one kept is the finalist",
        low=1,
        high=1000,
        source="docs/reproduce.md (a population's fittest is not its best in a maze)",
    )
    enough: float = setting(
        0.99,
        doc="a finalist that meets every validation target with every figure (successes and "
        "agreements, as rates) at least this ends its round: the finalists after it are not "
        "evolved (1: every finalist of the round is evolved)",
        low=0.0,
        high=1.0,
        source="docs/speed.md (finalists evolved only while needed)",
    )
    variants: int = setting(
        4, doc="starts per crossroad", low=1, high=100, source="docs/experiments.md"
    )
    approaches: tuple[str, ...] = setting(
        ("south", "west", "east"),
        doc="how the robot enters the crossroads (the LF search chooses on them too)",
        choices=APPROACHES,
        source="docs/reproduce.md (crossroads entered round a corner, as in a maze)",
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        try:
            check_approaches(self.approaches)
        except MbnInputError as exc:
            raise MbnInputError(f"lf.{exc}") from None


@dataclass(frozen=True)
class TestsSettings(Settings):
    """The tests (paper 3.1: 10 start positions, three consecutive crossroads)."""

    section = "tests"
    seconds: float = setting(
        90.0,
        doc="time limit of a trial",
        unit="s",
        low=1.0,
        high=3600.0,
        source="docs/reproduce.md",
    )
    mbn_seconds: float = setting(
        120.0,
        doc="time limit of an MBN trial (its junctions count from its first tile)",
        unit="s",
        low=1.0,
        high=3600.0,
        source="docs/reproduce.md",
    )
    jitter_per_mark: int = setting(
        20,
        doc="jittered trials per start mark of the test maze",
        low=1,
        high=1000,
        source="not in the paper",
    )
    heldout_repeats: int = setting(
        17,
        doc="trials per start mark of the held-out maze (the mark, then jittered ones)",
        low=1,
        high=1000,
        source="not in the paper",
    )
    maze: str = setting("fig4", doc="the test maze (the paper's Fig. 4)", source="paper Fig. 4")
    heldout_maze: str = setting(
        "heldout", doc="a maze no training and no choice ever sees", source="docs/reproduce.md"
    )

    def check_names(self, sections: Mapping[str, Settings], where: Locator) -> None:
        # read and runnable, with the tiles of the MBN the run tests in them (if any)
        rules = mbn_tile_rules(sections)
        for key in ("maze", "heldout_maze"):
            trial_maze(getattr(self, key), where(self.section, key), rules)
