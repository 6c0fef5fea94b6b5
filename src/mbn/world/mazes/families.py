"""Maze families: seeded generators of grid mazes, and the train / validation / test splits of
their seeds (``docs/generalization.md``).

A **family** (:class:`Family`) is a generator with its parameters: a maze of the family is
``generate(family, seed)``, the same for the same parameters and seed. :data:`FAMILIES` holds
the named ones, each registered by :func:`register_family` (a family of your own is registered
the same way, from outside ``mbn``, and is then named, selected and split as these are):

* ``grid`` — no tiles: the wall followers and the rules beyond them (every start judgeable under
  right, left, straight-right and straight-left);
* ``tiles2`` — the paper's two tile kinds (one colour: right, two colours: left);
* ``tiles3`` — three tile kinds (one, two, three colours: right, left, straight-right);
* ``tiles4``, ``tiles5``, ``tiles6`` — four, five, six tile kinds (those of ``tiles3``, then
  four colours straight-left, five right-left, six left-right: :data:`MANY_TILE_RULES`), in
  larger mazes (17-25, 19-27, 21-29 cells a side), their start marks chosen to judge every
  program (:func:`place_starts`);
* ``turns2`` .. ``turns6`` — the switch: the tile kinds and rules of ``tiles2`` .. ``tiles6``,
  every kind 0, 1, 2 and 3 cells before a junction, mid-corridor and on a corner before a
  junction (:attr:`Family.turn_tiles`: the program changes in the middle of a turn), in mazes two
  cells larger a side.

**The generator** (:func:`lattice_grid`) lays corridors one cell wide along a lattice of lines
``gap`` cells apart (the gaps drawn, so corridors between junctions run 1 to ``gap - 1`` cells),
then knocks out lattice segments at random while every free cell stays connected: what is left
has plus crossings, T junctions, corners (with junctions right after some of them, where two
lines are 2 cells apart), straight corridors through former crossings (long corridors), dead
ends and loops. Tiles (:func:`place_tiles`) lie across straight corridor cells ``0 .. reach``
cells before a T or plus crossing (``d`` free cells between the tile's cell and the junction's),
and in the middle of corridors (at least :data:`MID_CORRIDOR` cells from either end); with
``turn_tiles``, also on corners with a T or plus crossing along one of their arms, no tile
between (:func:`turn_leads`); start marks on straight corridor cells, facing either way along
the corridor.

**Every maze returned is checked** (:func:`check`): connected; one-cell corridors; the junction
kinds the family asks for present (corners, T junctions, plus crossings, and dead ends and loops
where its parameters make them); every start mark judgeable under every rule in use (the
followed route passes ``junctions`` decision cells; with tiles, for each first rule, a tile and
then ``junctions`` decision cells, :func:`mbn.world.junctions.rule_route`); every tile kind
present at every distance asked for, mid-corridor and on corners as asked; and, with tiles,
each tile kind's program judged (a swapped program takes a wrong exit from some start,
:func:`mbn.world.junctions.program_swaps_caught`). An attempt that fails a check is drawn again
from the same generator, so the result still depends on the seed alone; parameters that cannot
produce a valid maze are refused in one line naming the check that failed.

**Splits** (:data:`SPLITS`): three disjoint ranges of generator seeds, the same for every
built-in family: ``train`` (what evolution draws its episodes from), ``validation`` (the choice
among candidates and restarts) and ``test`` (:data:`TEST_SIZE` mazes, used by no selection of
any stage, setting or default: only ever a test). :func:`check_use` refuses a test seed for
training or validation. A family may have splits of its own (:attr:`Family.splits`). A test
maze somebody looked into (a report's picture of a failure, a diagnosis) is no longer a test:
:data:`LOOKED_INTO` moves it to the end of its family's validation split, and the test split
takes the next fresh seed after its range in its place (:func:`family_splits`).

**A family of your own** (:func:`register_family`): its parameters, its tile kinds and the rules
they put in force, its splits, and its generator of corridors (:attr:`Family.layout`, a
function of the family and a NumPy generator giving the free-cell mask; default
:func:`lattice_grid`); the tiles, start marks and checks are this module's (with a layout of
its own, a maze is checked for one-cell corridors, connected, the starts judgeable, the tiles
and the programs judged, not for the lattice's junction kinds). Registered, its name selects it
wherever a built-in's does (``[episodes] family``, ``NAME:SEED``, ``NAME/SPLIT``), and an MBN
whose tile rules are its ``tile_rules`` is validated and judged in its mazes
(:func:`mbn.experiments.stages.common.tile_family`)::

    register_family(Family("corridors", "...", tile_kinds=(1, 2), tile_rules=("right", "u-turn"),
                           first_rules=("right",), rules=("right", "u-turn")))

**Names** (:func:`parse_name`): ``FAMILY:SEED`` is one maze (``tiles2:2000007``);
``FAMILY/SPLIT`` a whole split (``grid/test``), ``FAMILY/SPLIT:A-B`` the split's mazes ``A`` to
``B`` (0-based, inclusive: ``grid/validation:0-9``); ``FAMILY/zero-shot`` the family's mazes of
the zero-shot suite (:data:`ZERO_SHOT`, hand-made built-ins). :func:`mbn.world.mazes.load.load_maze`
takes a single maze's name; ``mbn evaluate --maze`` takes a split too.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import re
from collections.abc import Callable, Container, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from mbn.errors import MbnInputError
from mbn.world.junctions import (
    STEPS,
    decision_cells,
    free_neighbours,
    mask_neighbours,
    program_swaps_caught,
    route_passes,
    rule_route,
)
from mbn.world.mazes.grid_text import parse_maze_text
from mbn.world.mazes.model import DEFAULT_CELL, TILE_COLORS, Maze
from mbn.world.rules import parse_rule, parse_rules

__all__ = [
    "CHOSEN_MARKS_ABOVE",
    "FAMILIES",
    "LOOKED_INTO",
    "MANY_TILE_RULES",
    "MID_CORRIDOR",
    "SPLITS",
    "START_MARKS",
    "TEST_SIZE",
    "ZERO_SHOT",
    "Family",
    "MazeName",
    "RetryError",
    "check",
    "check_use",
    "corner_cells",
    "describe",
    "family",
    "family_splits",
    "generate",
    "generate_text",
    "lattice_grid",
    "parse_name",
    "place_starts",
    "place_tiles",
    "register_family",
    "run_to_end",
    "split_seeds",
    "straight_cells",
    "tile_places",
    "turn_leads",
]

#: A mid-corridor tile lies at least this many cells from the decision cells (or dead ends) at
#: both ends of its corridor.
MID_CORRIDOR = 2
#: How many attempts :func:`generate` makes before it refuses the parameters.
ATTEMPTS = 200
#: A family of more tile kinds than this chooses its start marks to judge every program
#: (:func:`place_starts`).
CHOSEN_MARKS_ABOVE = 3
#: The number of mazes in each family's test split.
TEST_SIZE = 100
#: The generator seeds of each split, the same for every family (disjoint ranges). ``train`` is
#: as large as any schedule of episodes needs; ``validation`` and ``test`` are fixed lists.
SPLITS: dict[str, range] = {
    "train": range(0, 1_000_000),
    "validation": range(1_000_000, 1_000_000 + 100),
    "test": range(2_000_000, 2_000_000 + TEST_SIZE),
}
#: Test mazes somebody looked into, by family (``docs/generalization.md``, "Splits"): each
#: leaves its family's test split for the end of its validation split (after the members the
#: stages use, so no selection changes), and the test split takes the next fresh seeds after
#: its range, keeping :data:`TEST_SIZE` mazes (:func:`family_splits`). Only ever grows; every
#: ``results.json`` records it (``mazes_looked_into``).
LOOKED_INTO: dict[str, tuple[int, ...]] = {
    # the worst test maze of the fifth sweep's seed 7 for the three-behaviour MBN, opened in
    # its report (2026-12-08)
    "tiles3": (2_000_078,),
}
#: The zero-shot suite (``docs/generalization.md``): hand-made built-in mazes unlike the
#: generator's output, by the family whose rules every start mark of them is judgeable under
#: (:func:`register_family`'s ``zero_shot``). Only ever a test, reported apart from the test
#: split; ``FAMILY/zero-shot`` names them.
ZERO_SHOT: dict[str, tuple[str, ...]] = {}
#: What each split may be used for (:func:`check_use`).
_USES = {"train": ("train", "validation"), "validation": ("validation",), "test": ("test",)}

_N, _E, _S, _W = range(4)
#: The ``.maze`` start mark facing each compass direction (index N E S W).
START_MARKS = {_N: "^", _E: ">", _S: "v", _W: "<"}


@dataclass(frozen=True)
class Family:
    """A maze generator and its parameters (see the module docstring).

    Attributes:
        name: the family's name.
        doc: one line: what the family is for.
        size: the grid's extent in cells (outer wall included), each side drawn in this range
            (inclusive).
        gap: the distance in cells between neighbouring parallel lattice lines, drawn per line
            in this range (inclusive; 2 leaves one wall cell between two corridors).
        remove: the fraction of lattice segments knocked out (each kept where removing it
            would cut the maze in two).
        dead_ends: the chance that a removal that leaves a dead end is made (0: no dead ends).
        tile_kinds: the tile kinds placed (colours: 1 to 6); empty: no tiles.
        reach: tiles lie 0 .. ``reach`` cells before a T or plus crossing.
        near_tiles: tiles of each kind before junctions, their distances taking 0 .. ``reach``
            in turn (so ``reach + 1`` of them give every distance once).
        mid_tiles: tiles of each kind in the middle of a corridor.
        turn_tiles: tiles of each kind on corners (a cell with two free neighbours at a right
            angle), each with a T or plus crossing at the end of one of its arms and no tile
            between: the program changes in the middle of a turn, before that junction (0: none,
            and the generator draws exactly what it drew before the option existed).
        starts: start marks (the paper's test: 10 positions).
        rules: every start is judgeable under each of these rules.
        first_rules: with tiles, every start is judgeable from each of these first rules,
            following the tiles (a tile, then ``junctions`` decision cells).
        tile_rules: with tiles, the rule each tile kind puts in force.
        junctions: the decision cells a trial judges (the paper: 3).
        cell: the side of a cell (metres).
        layout: the generator of the free cells, ``layout(family, rng)`` giving a boolean mask
            ``(rows, columns)``, row 0 north, True free, the outer ring walls (it may raise
            :class:`RetryError` to be drawn again); None: :func:`lattice_grid`. With a layout of
            its own a maze is not asked for the lattice's junction kinds (:func:`check`).
        splits: the family's own ``train``, ``validation`` and ``test`` ranges of generator
            seeds (disjoint); None: :data:`SPLITS`.
    """

    name: str
    doc: str
    size: tuple[int, int] = (13, 19)
    gap: tuple[int, int] = (2, 6)
    remove: float = 0.35
    dead_ends: float = 0.25
    tile_kinds: tuple[int, ...] = ()
    reach: int = 3
    near_tiles: int = 4
    mid_tiles: int = 1
    turn_tiles: int = 0
    starts: int = 10
    rules: tuple[str, ...] = ("right", "left", "straight-right", "straight-left")
    first_rules: tuple[str, ...] = ()
    tile_rules: tuple[str, ...] = ()
    junctions: int = 3
    cell: float = DEFAULT_CELL
    layout: Callable[[Family, np.random.Generator], np.ndarray] | None = None
    splits: Mapping[str, range] | None = field(default=None, hash=False)

    def __post_init__(self) -> None:
        where = f"maze family {self.name!r}"
        if not isinstance(self.name, str) or not self.name:
            raise MbnInputError(f"a maze family's name is a string, got {self.name!r}")
        if self.layout is not None and not callable(self.layout):
            raise MbnInputError(f"{where}: layout must be a function (family, rng) -> free cells")
        if self.splits is not None:
            object.__setattr__(self, "splits", _checked_splits(self.splits, where))

        def pair(key: str, low: int) -> None:
            value = getattr(self, key)
            ok = (
                isinstance(value, tuple)
                and len(value) == 2
                and all(isinstance(v, int) and not isinstance(v, bool) for v in value)
                and low <= value[0] <= value[1]
            )
            if not ok:
                raise MbnInputError(
                    f"{where}: {key} must be two integers low <= high, low >= {low}, got {value!r}"
                )

        pair("size", 5)
        pair("gap", 2)
        for key in ("remove", "dead_ends"):
            value = getattr(self, key)
            if not (isinstance(value, int | float) and 0.0 <= value <= 1.0):
                raise MbnInputError(f"{where}: {key} must be in [0, 1], got {value!r}")
        for key, low in (
            ("reach", 0),
            ("near_tiles", 0),
            ("mid_tiles", 0),
            ("turn_tiles", 0),
            ("starts", 1),
        ):
            value = getattr(self, key)
            if not (isinstance(value, int) and not isinstance(value, bool) and value >= low):
                raise MbnInputError(f"{where}: {key} must be an integer >= {low}, got {value!r}")
        if not (isinstance(self.junctions, int) and 1 <= self.junctions <= 32):
            raise MbnInputError(f"{where}: junctions must be an integer in 1..32")
        if any(k not in TILE_COLORS for k in self.tile_kinds) or len(set(self.tile_kinds)) != len(
            self.tile_kinds
        ):
            raise MbnInputError(
                f"{where}: tile_kinds must be distinct colours among "
                f"{', '.join(map(str, TILE_COLORS))}, got {self.tile_kinds!r}"
            )
        for key in ("rules", "first_rules", "tile_rules"):
            value = getattr(self, key)
            if not isinstance(value, tuple):
                raise MbnInputError(f"{where}: {key} must be a tuple of rules, got {value!r}")
            # kept as the rules' names (an MBN's tile rules find the family by them)
            object.__setattr__(self, key, tuple(parse_rules(value, f"{where}: {key}")))
        if self.tile_kinds:
            if len(self.tile_rules) < max(self.tile_kinds):
                raise MbnInputError(
                    f"{where}: tile_rules must name a rule for every tile kind up to "
                    f"{max(self.tile_kinds)} colours, got {self.tile_rules!r}"
                )
            if not self.first_rules:
                raise MbnInputError(f"{where}: a family with tiles needs first_rules")
            if self.near_tiles + self.mid_tiles + self.turn_tiles < 1:
                raise MbnInputError(
                    f"{where}: a family with tiles needs near_tiles, mid_tiles or turn_tiles"
                )
        elif self.turn_tiles:
            raise MbnInputError(f"{where}: turn_tiles needs tile_kinds (tiles to lay on corners)")
        if not (self.cell > 0 and np.isfinite(self.cell)):
            raise MbnInputError(f"{where}: cell must be a number of metres > 0")

    def replace(self, **changes: Any) -> Family:
        """This family with some parameters changed (checked as a new family)."""
        unknown = sorted(set(changes) - {f.name for f in dataclasses.fields(Family)})
        if unknown:
            raise MbnInputError(
                f"maze family {self.name!r}: unknown parameter {unknown[0]!r} (known: "
                f"{', '.join(parameter_names())})"
            )
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """The parameters as JSON-ready values (recorded with every maze the family gives); a
        layout and splits of its own as ``module:name`` and ``[first, last]`` seeds."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name in _OWN and value is None:
                continue  # the built-in generator and splits: left out, as they always were
            if f.name == "turn_tiles" and not value:
                continue  # no corner tiles: left out, as the records were before the option
            if f.name == "layout":
                value = f"{value.__module__}:{getattr(value, '__qualname__', repr(value))}"
            elif f.name == "splits":
                value = {k: [r.start, r.stop - 1] for k, r in value.items()}
            out[f.name] = list(value) if isinstance(value, tuple) else value
        return out


#: The fields of a family that are not generator parameters of the lattice (and that the
#: ``--set`` of ``mbn mazes generate`` does not change).
_OWN = ("layout", "splits")


def parameter_names() -> list[str]:
    """The parameters a family takes (besides its name, doc, layout and splits)."""
    return [f.name for f in dataclasses.fields(Family) if f.name not in ("name", "doc", *_OWN)]


_SPLIT_NAMES = ("train", "validation", "test")


def _checked_splits(splits: Any, where: str) -> Mapping[str, range]:
    """A family's own splits, checked (the three names, ranges of seeds >= 0 step 1, none
    empty, disjoint), read-only, in the order train, validation, test."""
    if not isinstance(splits, Mapping) or sorted(splits) != sorted(_SPLIT_NAMES):
        got = sorted(splits) if isinstance(splits, Mapping) else repr(splits)
        raise MbnInputError(
            f"{where}: splits must map train, validation and test to ranges of seeds, got {got}"
        )
    for name in _SPLIT_NAMES:
        r = splits[name]
        if not (isinstance(r, range) and r.step == 1 and len(r) > 0 and r.start >= 0):
            raise MbnInputError(
                f"{where}: splits: {name} must be a non-empty range of seeds >= 0, got {r!r}"
            )
    for a, b in ((0, 1), (0, 2), (1, 2)):
        ra, rb = splits[_SPLIT_NAMES[a]], splits[_SPLIT_NAMES[b]]
        if ra.start < rb.stop and rb.start < ra.stop:
            raise MbnInputError(f"{where}: splits: {_SPLIT_NAMES[a]} and {_SPLIT_NAMES[b]} overlap")
    return MappingProxyType({name: splits[name] for name in _SPLIT_NAMES})


#: The named families, in the order of registration (:func:`register_family`).
FAMILIES: dict[str, Family] = {}
_FAMILY_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


def register_family(
    fam: Family, *, zero_shot: Sequence[str] = (), salt: int | None = None
) -> Family:
    """Register the family ``fam`` under its name (lower case, digits and ``_``: it is named
    ``NAME:SEED`` and ``NAME/SPLIT``): :func:`family` finds it, ``[episodes] family`` selects
    it, and an MBN whose tile rules are its ``tile_rules`` is judged in its mazes.
    ``zero_shot``: built-in mazes of its zero-shot suite (``NAME/zero-shot``); ``salt``: mixed
    into its generator's seed, so that two families' mazes of one seed differ (default: from
    its name). Registering an equal family again is allowed (a module imported twice); a name
    taken by another family is refused in one line."""
    if not isinstance(fam, Family):
        raise MbnInputError(f"register_family: expected a Family, got {type(fam).__name__}")
    where = f"register_family({fam.name!r})"
    if not _FAMILY_NAME.match(fam.name):
        raise MbnInputError(
            f"{where}: a family's name is lower-case letters, digits and '_' (my_family)"
        )
    suite = tuple(zero_shot)
    if suite:
        from mbn.world.mazes.builtin import BUILTIN_NAMES

        unknown = [n for n in suite if n not in BUILTIN_NAMES]
        if unknown:
            raise MbnInputError(f"{where}: zero_shot: {unknown[0]!r} is not a built-in maze")
    if salt is None:
        salt = int.from_bytes(hashlib.sha256(fam.name.encode()).digest()[:4], "big")
    if not (isinstance(salt, int) and not isinstance(salt, bool) and salt >= 0):
        raise MbnInputError(f"{where}: salt must be an integer >= 0, got {salt!r}")
    held = FAMILIES.get(fam.name)
    if held is not None:
        same = (
            held == fam
            and held.splits == fam.splits
            and ZERO_SHOT.get(fam.name, ()) == suite
            and _FAMILY_SALT[fam.name] == salt
        )
        if not same:
            raise MbnInputError(f"{where}: another family of that name is registered already")
        return held
    FAMILIES[fam.name] = fam
    _FAMILY_SALT[fam.name] = salt
    if suite:
        ZERO_SHOT[fam.name] = suite
    return fam


def family(name: str) -> Family:
    """The named family, or one line listing the names."""
    try:
        return FAMILIES[name]
    except KeyError:
        raise MbnInputError(
            f"unknown maze family {name!r} (known: {', '.join(FAMILIES)})"
        ) from None


def family_splits(fam: Family | str | None = None) -> Mapping[str, Sequence[int]]:
    """The splits of generator seeds of ``fam`` (a family or its name): its own, else
    :data:`SPLITS` (which None gives too), less the test mazes looked into
    (:data:`LOOKED_INTO`): those end its validation split, and its test split goes on past its
    range with as many fresh seeds."""
    if fam is None:
        return SPLITS
    fam = family(fam) if isinstance(fam, str) else fam
    base = fam.splits if fam.splits is not None else SPLITS
    looked = LOOKED_INTO.get(fam.name, ())
    return _moved(base, tuple(looked)) if looked else base


@functools.lru_cache(maxsize=64)
def _moved_cached(
    base: tuple[tuple[str, range], ...], looked: tuple[int, ...]
) -> Mapping[str, Sequence[int]]:
    ranges = dict(base)
    splits: dict[str, Sequence[int]] = dict(base)
    test = ranges["test"]
    if any(s not in test for s in looked):
        raise MbnInputError(f"looked-into mazes {list(looked)} must be test seeds ({_span(test)})")
    others = [r for name, r in ranges.items() if name != "test"]
    fresh: list[int] = []
    seed = test.start
    while len(fresh) < len(test):
        if seed not in looked and not any(seed in r for r in others):
            fresh.append(seed)
        seed += 1
    splits["validation"] = (*splits["validation"], *looked)
    splits["test"] = tuple(fresh)
    return MappingProxyType(splits)


def _moved(base: Mapping[str, range], looked: tuple[int, ...]) -> Mapping[str, Sequence[int]]:
    return _moved_cached(tuple(base.items()), looked)


# --------------------------------------------------------------------------------------------
# Splits and names
# --------------------------------------------------------------------------------------------


def split_seeds(
    split: str,
    first: int | None = None,
    last: int | None = None,
    fam: Family | str | None = None,
) -> list[int]:
    """The generator seeds of ``split`` (of the family ``fam``'s splits, :func:`family_splits`),
    or its members ``first`` .. ``last`` (0-based, inclusive). The train split is open-ended:
    it needs both."""
    splits = family_splits(fam)
    if split not in splits:
        raise MbnInputError(f"unknown split {split!r} (known: {', '.join(splits)})")
    seeds = splits[split]
    if first is None:
        if split == "train":
            raise MbnInputError("the train split is open-ended: name a range (train:0-99)")
        return list(seeds)
    last = first if last is None else last
    if not 0 <= first <= last < len(seeds):
        raise MbnInputError(
            f"split {split!r}: members {first}-{last} out of range (0-{len(seeds) - 1})"
        )
    return list(seeds[first : last + 1])


def split_of(seed: int, fam: Family | str | None = None) -> str:
    """The split a generator seed belongs to (of the family ``fam``'s splits; one line if
    none)."""
    splits = family_splits(fam)
    for name, seeds in splits.items():
        if seed in seeds:
            return name
    raise MbnInputError(
        f"maze seed {seed} is in no split (train {_span(splits['train'])}, validation "
        f"{_span(splits['validation'])}, test {_span(splits['test'])})"
    )


def _span(seeds: Sequence[int]) -> str:
    """``seeds`` as runs of consecutive seeds: ``1000000-1000099, 2000078``."""
    if isinstance(seeds, range):
        return f"{seeds.start}-{seeds.stop - 1}"
    runs: list[list[int]] = []
    for s in seeds:
        if runs and s == runs[-1][1] + 1:
            runs[-1][1] = s
        else:
            runs.append([s, s])
    return ", ".join(f"{a}-{b}" if a != b else f"{a}" for a, b in runs)


def check_use(
    seeds: Iterable[int], use: str, where: str = "", fam: Family | str | None = None
) -> None:
    """Refuse, in one line, a seed used for ``use`` (``train``, ``validation`` or ``test``)
    outside the splits (of the family ``fam``) that allow it: a test seed is only ever a test,
    a validation seed never trains."""
    if use not in ("train", "validation", "test"):
        raise ValueError(f"use must be train, validation or test, got {use!r}")
    prefix = f"{where}: " if where else ""
    for seed in seeds:
        split = split_of(int(seed), fam)
        if use not in _USES[split]:
            raise MbnInputError(
                f"{prefix}maze seed {seed} is in the {split} split, and {use} may not use it"
                + (" (a test maze is only ever a test)" if split == "test" else "")
            )


@dataclass(frozen=True)
class MazeName:
    """A parsed generated-maze name: one maze (``seeds`` of length 1, ``split`` None) or a split
    (or part of one)."""

    family: str
    seeds: tuple[int, ...]
    split: str | None
    builtins: tuple[str, ...] = ()

    @property
    def text(self) -> str:
        """The name, written back (``grid:7``, ``grid/test``, ``grid/validation:0-9``)."""
        if self.split is None:
            return f"{self.family}:{self.seeds[0]}"
        if self.split == "zero-shot":
            return f"{self.family}/zero-shot"
        seeds = family_splits(self.family)[self.split]
        if len(self.seeds) == len(seeds):
            return f"{self.family}/{self.split}"
        first, last = seeds.index(self.seeds[0]), seeds.index(self.seeds[-1])
        return f"{self.family}/{self.split}:{first}-{last}"


_ONE = re.compile(r"^([a-z][a-z0-9_]*):(\d+)$")
_SPLIT = re.compile(r"^([a-z][a-z0-9_]*)/([a-z-]+)(?::(\d+)(?:-(\d+))?)?$")


def parse_name(text: str) -> MazeName | None:
    """The generated maze(s) ``text`` names (``FAMILY:SEED``, ``FAMILY/SPLIT``,
    ``FAMILY/SPLIT:A-B``), None when it has neither form (a file or a built-in name), or one
    line saying what is wrong (an unknown family or split, a range out of the split)."""
    one, many = _ONE.match(text), _SPLIT.match(text)
    if one is None and many is None:
        return None
    name = (one or many).group(1)  # type: ignore[union-attr]
    family(name)  # refuses an unknown family
    if one is not None:
        seed = int(one.group(2))
        split_of(seed, name)  # refuses a seed outside every split
        return MazeName(name, (seed,), None)
    assert many is not None
    split = many.group(2)
    if split == "zero-shot":
        if many.group(3) is not None:
            raise MbnInputError(f"{text!r}: the zero-shot suite is named whole ({name}/zero-shot)")
        if name not in ZERO_SHOT:
            raise MbnInputError(f"{text!r}: the family {name!r} has no zero-shot suite")
        return MazeName(name, (), "zero-shot", ZERO_SHOT[name])
    first = None if many.group(3) is None else int(many.group(3))
    last = None if many.group(4) is None else int(many.group(4))
    return MazeName(name, tuple(split_seeds(split, first, last, name)), split)


# --------------------------------------------------------------------------------------------
# The generator
# --------------------------------------------------------------------------------------------


def _lines(rng: np.random.Generator, extent: int, gap: tuple[int, int]) -> list[int]:
    """Lattice line positions 1 .. extent - 2 with drawn gaps (the last line at the last
    position the gaps reach)."""
    lines = [1]
    while True:
        step = int(rng.integers(gap[0], gap[1] + 1))
        if lines[-1] + step > extent - 2:
            return lines
        lines.append(lines[-1] + step)


def lattice_grid(fam: Family, rng: np.random.Generator) -> np.ndarray:
    """A free-cell mask ``(R, C)`` (row 0 north) of corridors along a lattice with segments
    knocked out (see the module docstring); connected."""
    cols = int(rng.integers(fam.size[0], fam.size[1] + 1))
    rows = int(rng.integers(fam.size[0], fam.size[1] + 1))
    xs, ys = _lines(rng, cols, fam.gap), _lines(rng, rows, fam.gap)
    if len(xs) < 2 or len(ys) < 2:
        raise _RetryError("the lattice has fewer than two lines each way")
    cols, rows = xs[-1] + 2, ys[-1] + 2
    # nodes (i, j) at (ys[i], xs[j]); segments between neighbouring nodes
    segments = [((i, j), (i, j + 1)) for i in range(len(ys)) for j in range(len(xs) - 1)]
    segments += [((i, j), (i + 1, j)) for i in range(len(ys) - 1) for j in range(len(xs))]
    kept = set(range(len(segments)))
    degree: dict[tuple[int, int], int] = {}
    for a, b in segments:
        degree[a] = degree.get(a, 0) + 1
        degree[b] = degree.get(b, 0) + 1
    for k in rng.permutation(len(segments)):
        if rng.random() >= fam.remove:
            continue
        a, b = segments[int(k)]
        if degree[a] == 1 or degree[b] == 1:
            continue  # it would leave a node cut off
        if (degree[a] == 2 or degree[b] == 2) and rng.random() >= fam.dead_ends:
            continue  # it would leave a dead end
        if not _connected_without(segments, kept - {int(k)}):
            continue
        kept.discard(int(k))
        degree[a] -= 1
        degree[b] -= 1
    free = np.zeros((rows, cols), dtype=bool)
    for k in kept:
        (i0, j0), (i1, j1) = segments[k]
        free[ys[i0] : ys[i1] + 1, xs[j0] : xs[j1] + 1] = True
    return free


def _connected_without(segments: list, kept: set[int]) -> bool:
    """Whether the nodes stay connected by the ``kept`` segments."""
    adjacency: dict[tuple[int, int], list[tuple[int, int]]] = {}
    for k in kept:
        a, b = segments[k]
        adjacency.setdefault(a, []).append(b)
        adjacency.setdefault(b, []).append(a)
    nodes = {n for s in segments for n in s}
    if set(adjacency) != nodes:
        return False
    start = next(iter(adjacency))
    seen, stack = {start}, [start]
    while stack:
        for n in adjacency[stack.pop()]:
            if n not in seen:
                seen.add(n)
                stack.append(n)
    return len(seen) == len(nodes)


class RetryError(MbnInputError):
    """An attempt that failed a check (the reason); :func:`generate` draws again (a family's
    own layout may raise it too)."""


_RetryError = RetryError


def straight_cells(free: np.ndarray) -> np.ndarray:
    """Straight corridor cells of the free-cell mask ``free``: free, exactly two free
    neighbours, opposite."""
    nb = mask_neighbours(free)
    count = nb.sum(-1)
    return free & (count == 2) & ((nb[..., _N] & nb[..., _S]) | (nb[..., _E] & nb[..., _W]))


def run_to_end(straight: np.ndarray, r: int, c: int, h: int) -> int:
    """Straight corridor cells (the mask ``straight``, :func:`straight_cells`) from ``(r, c)``
    (excluded) in direction ``h`` up to the first cell that is not one (the corridor's end: a
    decision cell or a dead end)."""
    n = 0
    dr, dc = STEPS[h]
    r, c = r + dr, c + dc
    while 0 <= r < straight.shape[0] and 0 <= c < straight.shape[1] and straight[r, c]:
        n += 1
        r, c = r + dr, c + dc
    return n


def corner_cells(free: np.ndarray) -> np.ndarray:
    """Corner cells of the free-cell mask ``free``: free, exactly two free neighbours, at a right
    angle."""
    nb = mask_neighbours(free)
    count = nb.sum(-1)
    return free & (count == 2) & ~((nb[..., _N] & nb[..., _S]) | (nb[..., _E] & nb[..., _W]))


def turn_leads(
    free: np.ndarray, r: int, c: int, tiles: Iterable[tuple[int, int]] = ()
) -> list[list[tuple[int, int]]]:
    """The arms of the corner ``(r, c)`` of the free-cell mask ``free`` that run through
    straight corridor cells, none of them in ``tiles``, to a T or plus crossing: each as the
    straight cells between the corner and the crossing (none where the crossing is next to the
    corner), in the order N E S W of the arm."""
    nb = mask_neighbours(free)
    count = np.where(free, nb.sum(-1), 0)
    return _leads(nb, count, straight_cells(free), r, c, set(tiles))


def _leads(
    nb: np.ndarray,
    count: np.ndarray,
    straight: np.ndarray,
    r: int,
    c: int,
    held: Container[tuple[int, int]],
) -> list[list[tuple[int, int]]]:
    """:func:`turn_leads` from the mask's neighbours, their counts (0 in walls) and straight
    cells, the tiles ``held``."""
    leads = []
    for h in range(4):
        if not nb[r, c, h]:
            continue
        n = run_to_end(straight, r, c, h)
        dr, dc = STEPS[h]
        cells = [(r + dr * (i + 1), c + dc * (i + 1)) for i in range(n)]
        if count[r + dr * (n + 1), c + dc * (n + 1)] >= 3 and not any(x in held for x in cells):
            leads.append(cells)
    return leads


def _place_turn_tiles(
    fam: Family,
    free: np.ndarray,
    rng: np.random.Generator,
    tiles: dict[tuple[int, int], tuple[int, str]],
    kept_clear: set[tuple[int, int]],
) -> None:
    """:func:`place_tiles`'s corner tiles: ``fam.turn_tiles`` of each kind into ``tiles``, and
    the straight cells of one arm of each, drawn, into ``kept_clear``."""
    nb = mask_neighbours(free)
    count = np.where(free, nb.sum(-1), 0)
    straight = straight_cells(free)
    corners = [(int(r), int(c)) for r, c in np.argwhere(corner_cells(free))]
    for kind in fam.tile_kinds:
        for _ in range(fam.turn_tiles):
            options: list[tuple[int, int, list[list[tuple[int, int]]]]] = []
            for r, c in corners:
                if (r, c) in tiles or any((r + dr, c + dc) in tiles for dr, dc in STEPS):
                    continue
                leads = _leads(nb, count, straight, r, c, tiles)
                if leads:
                    options.append((r, c, leads))
            if not options:
                raise _RetryError(
                    f"no corner with a T or plus crossing along an arm for a {kind}-colour tile"
                )
            r, c, leads = options[int(rng.integers(len(options)))]
            tiles[(r, c)] = (kind, "turn")
            kept_clear.update(leads[int(rng.integers(len(leads)))])


def place_tiles(
    fam: Family, free: np.ndarray, rng: np.random.Generator
) -> dict[tuple[int, int], tuple[int, str]]:
    """Tile cells ``{(row, col): (colours, where)}``, ``where`` ``"d=K"`` (K cells before a T or
    plus crossing), ``"mid"`` (the middle of a corridor) or ``"turn"`` (a corner, with
    ``fam.turn_tiles``); no two tiles side by side.

    With ``turn_tiles`` the corner tiles are drawn first (corners are fewer than corridor
    cells), each on a corner with a T or plus crossing at the end of one of its arms
    (:func:`turn_leads`); the straight cells of one such arm, drawn, are kept free of tiles, so
    that the corner's tile is the last before that crossing. Without, nothing of this is drawn
    and the tiles are those the generator always drew."""
    nb = mask_neighbours(free)
    count = nb.sum(-1)
    straight = straight_cells(free)
    junction_cells = [tuple(map(int, rc)) for rc in np.argwhere(free & (count >= 3))]
    tiles: dict[tuple[int, int], tuple[int, str]] = {}
    kept_clear: set[tuple[int, int]] = set()  # the arms leading from corner tiles to crossings

    def allowed(r: int, c: int) -> bool:
        if not straight[r, c] or (r, c) in tiles or (r, c) in kept_clear:
            return False
        return all((r + dr, c + dc) not in tiles for dr, dc in STEPS)

    if fam.turn_tiles:
        _place_turn_tiles(fam, free, rng, tiles, kept_clear)
    for kind in fam.tile_kinds:
        for k in range(fam.near_tiles):
            d = k % (fam.reach + 1)
            options = []
            for r, c in junction_cells:
                for h in range(4):
                    if not nb[r, c, h]:
                        continue
                    dr, dc = STEPS[h]
                    cells = [(r + dr * (i + 1), c + dc * (i + 1)) for i in range(d + 1)]
                    if all(
                        0 <= rr < free.shape[0] and 0 <= cc < free.shape[1] and straight[rr, cc]
                        for rr, cc in cells
                    ) and allowed(*cells[-1]):
                        options.append(cells[-1])
            if not options:
                raise _RetryError(
                    f"no corridor cell {d} cells before a junction for a {kind}-colour tile"
                )
            tiles[options[int(rng.integers(len(options)))]] = (kind, f"d={d}")
        for _ in range(fam.mid_tiles):
            options = [
                (int(r), int(c))
                for r, c in np.argwhere(straight)
                if allowed(int(r), int(c))
                and min(
                    run_to_end(straight, int(r), int(c), h)
                    for h in range(4)
                    if nb[int(r), int(c), h]
                )
                >= MID_CORRIDOR
            ]
            if not options:
                raise _RetryError(f"no corridor long enough for a mid-corridor {kind}-colour tile")
            tiles[options[int(rng.integers(len(options)))]] = (kind, "mid")
    return tiles


def _grid_text(fam: Family, seed: int | None, chars: np.ndarray, notes: Sequence[str]) -> str:
    if seed is None:  # a grid being built
        head = [f"name = {fam.name}", f"cell = {fam.cell:g}"]
    else:
        head = [
            f"; {fam.name}:{seed}: a generated maze of the family {fam.name!r} ({fam.doc}),",
            f"; split {split_of(seed, fam)}; made by mbn.world.mazes.families.generate.",
            *[f"; {n}" for n in notes],
            f"name = {fam.name}:{seed}",
            f"cell = {fam.cell:g}",
        ]
    return "\n".join([*head, *("".join(row) for row in chars)]) + "\n"


def _attempt(fam: Family, seed: int, rng: np.random.Generator) -> tuple[str, Maze]:
    free = lattice_grid(fam, rng) if fam.layout is None else _own_layout(fam, rng)
    problems = _structure(free, fam)
    if problems:
        raise _RetryError(problems[0])
    chars = np.where(free, ".", "#").astype("<U1")
    tiles = place_tiles(fam, free, rng) if fam.tile_kinds else {}
    for (r, c), (kind, _) in tiles.items():
        chars[r, c] = str(kind)
    for r, c, h in place_starts(fam, chars, rng, f"{fam.name}:{seed}"):
        chars[r, c] = START_MARKS[h]
    notes = []
    if tiles:
        where = sorted({w for _, w in tiles.values()}, key=lambda w: (w == "mid", w))
        notes.append(f"tiles: {len(tiles)} ({', '.join(where)})")
    text = _grid_text(fam, seed, chars, notes)
    maze = parse_maze_text(text, f"{fam.name}:{seed}", source=f"{fam.name}:{seed}")
    problems = check(maze, fam)
    if problems:
        raise _RetryError(problems[0])
    return text, maze


def _own_layout(fam: Family, rng: np.random.Generator) -> np.ndarray:
    """The free cells a family's own layout draws, checked: a 2-D boolean mask, at least 3 x 3,
    its outer ring walls."""
    assert fam.layout is not None
    free = fam.layout(fam, rng)
    ok = (
        isinstance(free, np.ndarray)
        and free.dtype == bool
        and free.ndim == 2
        and min(free.shape) >= 3
    )
    if not ok:
        raise MbnInputError(
            f"maze family {fam.name!r}: its layout must give a 2-D boolean NumPy array of at "
            f"least 3 x 3 cells (True: free), got {type(free).__name__}"
            + (f" {free.dtype} {free.shape}" if isinstance(free, np.ndarray) else "")
        )
    if free[0].any() or free[-1].any() or free[:, 0].any() or free[:, -1].any():
        raise MbnInputError(
            f"maze family {fam.name!r}: its layout left a free cell on the outer ring (walls)"
        )
    return free


def place_starts(
    fam: Family, chars: np.ndarray, rng: np.random.Generator, where: str = "<maze>"
) -> list[tuple[int, int, int]]:
    """``fam.starts`` start marks ``(row, col, heading index N E S W)`` for the grid ``chars``
    (``#`` wall, ``.`` free, digits tiles): straight corridor cells without a tile, facing along
    the corridor, drawn in a random order (``rng``) and each kept when it is judgeable under
    every rule of ``fam`` (at most one mark a cell). Too few judgeable cells: a retry.

    A family of more than :data:`CHOSEN_MARKS_ABOVE` tile kinds chooses its marks instead
    (:func:`_chosen_marks`): those that judge the most programs not yet judged, then the rest
    in the drawn order (the families of up to three kinds keep the first judgeable ones)."""
    free = chars != "#"
    straight = straight_cells(free)
    nb = mask_neighbours(free)
    candidates = [
        (int(r), int(c), h)
        for r, c in np.argwhere(straight)
        if chars[r, c] == "."
        for h in range(4)
        if nb[r, c, h]
    ]
    order = rng.permutation(len(candidates))
    base = parse_maze_text(_grid_text(fam, None, chars, ()), where)
    if len(fam.tile_kinds) > CHOSEN_MARKS_ABOVE:
        return _chosen_marks(fam, base, free.shape[0], [candidates[int(k)] for k in order])
    marks: list[tuple[int, int, int]] = []
    used: set[tuple[int, int]] = set()
    for k in order:
        r, c, h = candidates[int(k)]
        if (r, c) in used:
            continue
        pose = ((c + 0.5) * fam.cell, (free.shape[0] - 1 - r + 0.5) * fam.cell, _heading(h))
        if _judgeable(fam, base, pose):
            marks.append((r, c, h))
            used.add((r, c))
            if len(marks) == fam.starts:
                return marks
    raise _RetryError(f"only {len(marks)} of {fam.starts} start marks judgeable under every rule")


def _chosen_marks(
    fam: Family, maze: Maze, rows: int, drawn: list[tuple[int, int, int]]
) -> list[tuple[int, int, int]]:
    """:func:`place_starts`'s marks for a family of many tile kinds: of the judgeable
    candidates ``drawn`` (in the drawn order), one at a time the mark that catches the most
    program swaps (:func:`mbn.world.junctions.program_swaps_caught`: a tile kind's rule swapped
    for another's, from each first rule) no mark chosen catches yet, the first drawn among
    equals, until every swap is caught or no mark catches one more; then the first judgeable
    ones drawn. With six kinds there are 30 swaps from each first rule, and 10 marks drawn at
    random catch them all in few mazes."""
    tile_rules = tuple(fam.tile_rules[: max(fam.tile_kinds)])
    rules = {name: parse_rule(name) for name in tile_rules}
    swaps = [
        (k, rules[w])
        for k, r in enumerate(tile_rules, 1)
        if k in fam.tile_kinds
        for w in rules
        if rules[w] != rules[r]
    ]
    judged: list[tuple[tuple[int, int, int], set[tuple[int, int]]]] = []
    for r, c, h in drawn:
        pose = ((c + 0.5) * fam.cell, (rows - 1 - r + 0.5) * fam.cell, _heading(h))
        if not _judgeable(fam, maze, pose):
            continue
        caught: set[tuple[int, int]] = set()
        for f, first in enumerate(fam.first_rules):
            passes = route_passes(
                maze, pose, first, fam.junctions, follow_tiles=True, tile_rules=tile_rules
            )
            for s, (k, w) in enumerate(swaps):
                if any(
                    p.source == k and w.exit(p.open_exits) != rules[p.rule].exit(p.open_exits)
                    for p in passes or ()
                ):
                    caught.add((f, s))
        judged.append(((r, c, h), caught))
    marks: list[tuple[int, int, int]] = []
    used: set[tuple[int, int]] = set()
    missing = set().union(*(caught for _, caught in judged))
    while missing and len(marks) < fam.starts:
        best, gain = None, 0
        for mark, caught in judged:  # in the drawn order: the first among equals
            if mark[:2] not in used and len(caught & missing) > gain:
                best, gain = (mark, caught), len(caught & missing)
        if best is None:
            break
        marks.append(best[0])
        used.add(best[0][:2])
        missing -= best[1]
    for mark, _ in judged:
        if len(marks) == fam.starts:
            break
        if mark[:2] not in used:
            marks.append(mark)
            used.add(mark[:2])
    if len(marks) < fam.starts:
        raise _RetryError(
            f"only {len(marks)} of {fam.starts} start marks judgeable under every rule"
        )
    return marks


def _heading(h: int) -> float:
    return {_N: np.pi / 2, _E: 0.0, _S: -np.pi / 2, _W: np.pi}[h]


def _judgeable(fam: Family, maze: Maze, pose: tuple[float, float, float]) -> bool:
    for rule in fam.rules:
        if rule_route(maze, pose, rule, fam.junctions) is None:
            return False
    for first in fam.first_rules if fam.tile_kinds else ():
        route = rule_route(
            maze,
            pose,
            first,
            fam.junctions,
            follow_tiles=True,
            count_from_tile=True,
            tile_rules=fam.tile_rules,
        )
        if route is None:
            return False
    return True


def _structure(free: np.ndarray, fam: Family) -> list[str]:
    """What the free-cell mask ``free`` lacks of the family's structure: one-cell corridors,
    connected, corners, T junctions, plus crossings, and a junction right after a corner (where
    lines can be 3 cells apart or less), dead ends and loops (where the parameters make them)."""
    problems: list[str] = []
    nb = mask_neighbours(free)
    count = np.where(free, nb.sum(-1), 0)
    straight = (nb[..., _N] & nb[..., _S]) | (nb[..., _E] & nb[..., _W])
    corners = free & (count == 2) & ~straight
    if np.any(free[1:, 1:] & free[:-1, 1:] & free[1:, :-1] & free[:-1, :-1]):
        problems.append("a corridor is more than one cell wide")
    if not _all_connected(free):
        problems.append("not every free cell is connected")
    if fam.layout is not None:
        return problems  # a layout of its own: the lattice's junction kinds are not asked for
    if not corners.any():
        problems.append("no corner")
    if not (count == 3).any():
        problems.append("no T junction")
    if not (count == 4).any():
        problems.append("no plus crossing")
    if fam.dead_ends > 0 and fam.remove > 0 and not (count == 1).any():
        problems.append("no dead end")
    if fam.remove < 1 and _loops(free) < 1:
        problems.append("no loop")
    if fam.gap[0] <= 3 and not _junction_after_corner(free, corners, count):
        problems.append("no junction right after a corner (2 cells or fewer)")
    return problems


def _loops(free: np.ndarray) -> int:
    """Independent loops of a connected free-cell mask: links between free neighbours minus
    cells plus one."""
    links = int((free[1:] & free[:-1]).sum() + (free[:, 1:] & free[:, :-1]).sum())
    return links - int(free.sum()) + 1


def check(maze: Maze, fam: Family) -> list[str]:
    """What ``maze`` lacks to be a maze of ``fam`` (see the module docstring); empty when it is
    one."""
    problems = _structure(np.asarray(maze.grid) != "#", fam)
    for k, start in enumerate(maze.starts, 1):
        x, y, theta = (float(v) for v in start)
        if not _judgeable(fam, maze, (x, y, theta)):
            problems.append(f"start #{k} is not judgeable under every rule in use")
            break
    if len(maze.starts) < fam.starts:
        problems.append(f"{len(maze.starts)} start marks, the family asks for {fam.starts}")
    if fam.tile_kinds:
        kinds = {t.colors for t in maze.tiles}
        missing = sorted(set(fam.tile_kinds) - kinds)
        if missing:
            problems.append(f"no tile of {missing[0]} colours")
        places = tile_places(maze)
        for kind in fam.tile_kinds:
            mine = [p for p in places if p["colors"] == kind]
            for d in sorted({k % (fam.reach + 1) for k in range(fam.near_tiles)}):
                if not any(d in p["before"] for p in mine if not p["corner"]):
                    problems.append(f"no {kind}-colour tile {d} cells before a junction")
            if sum(p["mid"] for p in mine) < fam.mid_tiles:
                problems.append(f"fewer than {fam.mid_tiles} mid-corridor {kind}-colour tiles")
            if sum(p["turn"] for p in mine) < fam.turn_tiles:
                problems.append(
                    f"fewer than {fam.turn_tiles} {kind}-colour tiles on a corner before a junction"
                )
        for first in fam.first_rules:
            caught = program_swaps_caught(
                maze, first, fam.junctions, tuple(fam.tile_rules[: max(fam.tile_kinds)])
            )
            blind = [key for key, n in caught.items() if n == 0 and key[0] in fam.tile_kinds]
            if blind:
                k, w = blind[0]
                problems.append(
                    f"from first rule {first}, no start catches the {k}-colour tile's program "
                    f"swapped for {w}"
                )
                break
    return problems


def tile_places(maze: Maze) -> list[dict[str, Any]]:
    """Where each tile of a grid maze lies, in the order of ``maze.tiles``: ``colors``;
    ``before``, the distances (free cells between) to the T or plus crossings at the ends of its
    corridor (for a tile on a corner, of its two arms), one per end that is one; ``mid``,
    whether it lies at least :data:`MID_CORRIDOR` cells from both ends of its corridor;
    ``corner``, whether it lies on a corner; ``turn``, whether on a corner with a T or plus
    crossing at the end of one of its arms and no tile between (:func:`turn_leads`)."""
    from mbn.world.junctions import cell_of

    free = np.asarray(maze.grid) != "#"
    nb = mask_neighbours(free)
    count = np.where(free, nb.sum(-1), 0)
    straight = straight_cells(free)
    corners = corner_cells(free)
    cells = [cell_of(maze, t.x, t.y) for t in maze.tiles]
    held = set(cells)
    out = []
    for tile, (r, c) in zip(maze.tiles, cells, strict=True):
        before, runs = [], []
        for h in range(4):
            if not nb[r, c, h]:
                continue
            n = run_to_end(straight, r, c, h)
            runs.append(n)
            dr, dc = STEPS[h]
            end = (r + dr * (n + 1), c + dc * (n + 1))
            if count[end] >= 3:
                before.append(n)
        out.append(
            {
                "colors": tile.colors,
                "before": sorted(before),
                "mid": bool(runs)
                and min(runs) >= MID_CORRIDOR
                and len(runs) == 2
                and not corners[r, c],
                "corner": bool(corners[r, c]),
                "turn": bool(corners[r, c]) and bool(_leads(nb, count, straight, r, c, held)),
            }
        )
    return out


def _all_connected(free: np.ndarray) -> bool:
    cells = np.argwhere(free)
    if len(cells) == 0:
        return False
    seen = np.zeros_like(free)
    stack = [tuple(map(int, cells[0]))]
    seen[stack[0]] = True
    while stack:
        r, c = stack.pop()
        for dr, dc in STEPS:
            rr, cc = r + dr, c + dc
            inside = 0 <= rr < free.shape[0] and 0 <= cc < free.shape[1]
            if inside and free[rr, cc] and not seen[rr, cc]:
                seen[rr, cc] = True
                stack.append((rr, cc))
    return bool(seen.sum() == free.sum())


def _junction_after_corner(free: np.ndarray, corners: np.ndarray, count: np.ndarray) -> bool:
    """Whether some corner has a T or plus crossing at most 2 cells along one of its arms."""
    nb = mask_neighbours(free)
    for r, c in np.argwhere(corners):
        for h in range(4):
            if not nb[r, c, h]:
                continue
            dr, dc = STEPS[h]
            for i in (1, 2):
                rr, cc = int(r) + dr * i, int(c) + dc * i
                if not (0 <= rr < free.shape[0] and 0 <= cc < free.shape[1]) or not free[rr, cc]:
                    break
                if count[rr, cc] >= 3:
                    return True
                if count[rr, cc] != 2:
                    break
    return False


@functools.lru_cache(maxsize=512)
def _generate(fam: Family, seed: int) -> tuple[str, Maze]:
    rng = np.random.default_rng([seed, _FAMILY_SALT.get(fam.name.split("-")[0], 0)])
    last = ""
    for _ in range(ATTEMPTS):
        try:
            return _attempt(fam, seed, rng)
        except _RetryError as exc:
            last = str(exc)
    raise MbnInputError(
        f"maze family {fam.name!r}: no valid maze for seed {seed} in {ATTEMPTS} attempts "
        f"(the last: {last}); the parameters cannot produce one"
    )


#: Mixed into a family's generator seed, so that two families' mazes of one seed differ (a
#: family with changed parameters, ``grid-custom``, keeps its family's): by
#: :func:`register_family`.
_FAMILY_SALT: dict[str, int] = {}


def generate(fam: Family | str, seed: int) -> Maze:
    """The maze of ``fam`` (a family or its name) for generator ``seed`` (checked; the same for
    the same parameters and seed)."""
    fam = family(fam) if isinstance(fam, str) else fam
    split_of(seed, fam)
    return _generate(fam, int(seed))[1]


def generate_text(fam: Family | str, seed: int) -> str:
    """The ``.maze`` text of :func:`generate`'s maze (what ``mbn mazes generate`` writes; read
    back, it is the same maze)."""
    fam = family(fam) if isinstance(fam, str) else fam
    split_of(seed, fam)
    return _generate(fam, int(seed))[0]


def describe(maze: Maze) -> dict[str, Any]:
    """What a grid maze holds (for tables and records): cells, decision cells by kind, dead
    ends, loops, tiles by kind (1, 2 and 3 colours, and more where it has them), start marks."""
    free = np.asarray(maze.grid) != "#"
    nb = free_neighbours(maze)
    count = nb.sum(-1)
    decision = decision_cells(maze)
    kinds = sorted({1, 2, 3} | {t.colors for t in maze.tiles})  # 1 to 3 always, as they were
    return {
        "name": maze.name,
        "shape": list(free.shape),
        "free_cells": int(free.sum()),
        "corners": int((decision & (count == 2)).sum()),
        "t_junctions": int((free & (count == 3)).sum()),
        "plus_crossings": int((free & (count == 4)).sum()),
        "dead_ends": int((free & (count == 1)).sum()),
        "loops": _loops(free),
        "tiles": {str(k): sum(t.colors == k for t in maze.tiles) for k in kinds},
        "starts": len(maze.starts),
    }


# --------------------------------------------------------------------------------------------
# mbn's families: registered as a family of your own is
# --------------------------------------------------------------------------------------------

register_family(
    Family("grid", "no tiles: the wall followers and the rules beyond them"),
    zero_shot=("zs_long", "zs_dense", "zs_hall", "zs_spiral", "zs_comb", "zs_stairs"),
    salt=1,
)
register_family(
    Family(
        "tiles2",
        "the paper's two tile kinds: one colour right, two colours left",
        size=(15, 21),
        tile_kinds=(1, 2),
        rules=("right", "left"),
        first_rules=("right", "left"),
        tile_rules=("right", "left"),
    ),
    zero_shot=("fig4", "heldout", "zs_far_tiles2", "zs_dense_tiles2"),
    salt=2,
)
register_family(
    Family(
        "tiles3",
        "three tile kinds: one colour right, two left, three straight-right",
        size=(15, 23),
        tile_kinds=(1, 2, 3),
        rules=("right", "left", "straight-right", "straight-left"),
        first_rules=("right", "left"),
        tile_rules=("right", "left", "straight-right"),
    ),
    zero_shot=("tiles3_heldout", "zs_far_tiles3"),
    salt=3,
)
#: The rules of the tile kinds of ``tiles4``, ``tiles5`` and ``tiles6``: kind ``k`` (``k``
#: colours) puts the ``k``-th in force.
MANY_TILE_RULES = ("right", "left", "straight-right", "straight-left", "right-left", "left-right")
for _kinds, _doc in (
    (4, "four tile kinds: one colour right, two left, three straight-right, four straight-left"),
    (5, "five tile kinds: those of tiles4, and five colours right-left"),
    (6, "six tile kinds: those of tiles5, and six colours left-right"),
):
    register_family(
        Family(
            f"tiles{_kinds}",
            _doc,
            size=(2 * _kinds + 9, 2 * _kinds + 17),
            tile_kinds=tuple(range(1, _kinds + 1)),
            rules=MANY_TILE_RULES[: max(4, _kinds)],
            first_rules=("right", "left"),
            tile_rules=MANY_TILE_RULES[:_kinds],
        ),
        salt=_kinds,
    )
#: The families of the switch: ``turns2`` .. ``turns6`` are ``tiles2`` .. ``tiles6`` (their tile
#: kinds, tile rules, first rules and rules) with a tile of each kind also on a corner, before a
#: T or plus crossing (:attr:`Family.turn_tiles`), and every distance 0 .. 3 before a junction
#: asked of every kind, in mazes two cells larger a side.
for _kinds in range(2, 7):
    _tiles = FAMILIES[f"tiles{_kinds}"]
    register_family(
        dataclasses.replace(
            _tiles,
            name=f"turns{_kinds}",
            doc=f"the switch: the tiles of tiles{_kinds} 0, 1, 2 and 3 cells before a junction "
            "and on corners (the program changes mid-turn)",
            size=(_tiles.size[0] + 2, _tiles.size[1] + 2),
            reach=3,
            near_tiles=4,
            turn_tiles=1,
        ),
        salt=5 + _kinds,
    )
