"""What a run's settings name — the mazes its trials run in, the connections of the followers'
network, the rules a stage needs from another — checked before the run does any work.

Each settings class that names something checks it in
:meth:`~mbn.config.Settings.check_names`, which the runner calls for every section of an
experiment's config before it writes or clears anything
(:meth:`~mbn.experiments.pipeline.runconfig.RunConfig.check`): a maze that cannot be read, or
has no start marks, or lacks the tiles an MBN is tested with, is refused in one line at the
start, not when its stage reads it after an hour of evolution.

A maze used to choose among candidates during evolution (``[validation] maze``, ``extra_mazes``,
``[programs] validation_mazes``) must not be one a test runs in (``[tests]``, ``[tests3]``):
held-out and test mazes are only ever a test. Two mazes are the same when they have the same
name, or the same walls, tiles and start marks (a copy of ``fig4`` under another name is
``fig4``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from mbn.errors import MbnInputError

if TYPE_CHECKING:
    from mbn.config import Locator, Settings
    from mbn.networks.programmable import Connection
    from mbn.world.mazes.model import Maze

__all__ = [
    "FOLLOWER_INPUTS",
    "FOLLOWER_NEURONS",
    "PAPER_TILE_RULES",
    "check_not_test_mazes",
    "follower_connections",
    "locate",
    "mbn_tile_rules",
    "same_maze",
    "test_mazes",
    "trial_maze",
]

#: The followers' network (RF, LF, and the interpreters built on RF): 3 neurons, 3 inputs.
FOLLOWER_NEURONS = 3
FOLLOWER_INPUTS = 3
#: The rules the paper's tiles put in force (one colour right, two colours left).
PAPER_TILE_RULES = ("right", "left")


def trial_maze(name: str, where: str, tile_rules: Sequence[str] | None = None) -> Maze:
    """The maze ``name`` (a built-in name or a file) as a trial runs in it, or one line
    ``where: ...``: it must be read, be a grid maze with start marks and, where an MBN is tested
    in it (``tile_rules``: the rule a tile of 1, 2, ... colours puts in force), have tiles of no
    more colours than there are rules."""
    from mbn.experiments.trials import TrialSpec
    from mbn.world.mazes.load import load_maze

    try:
        maze = load_maze(name)
        TrialSpec().check_maze(maze)  # start marks, a grid
    except MbnInputError as exc:
        raise MbnInputError(f"{where}: {exc}") from None
    if tile_rules is not None:
        colours = max((t.colors for t in maze.tiles), default=0)
        if not colours:
            raise MbnInputError(
                f"{where}: maze {maze.name!r} has no tiles, and an MBN is tested in it (the last "
                "tile it drove over sets its rule)"
            )
        if colours > len(tile_rules):
            raise MbnInputError(
                f"{where}: maze {maze.name!r} has {colours}-colour tiles, and the MBN tested in "
                f"it knows rules for tiles of up to {len(tile_rules)} colours "
                f"({', '.join(tile_rules)})"
            )
    return maze


def same_maze(a: Maze, b: Maze) -> bool:
    """Whether two mazes are the same world: walls, bounds, tiles and start marks."""
    return (
        a.bounds == b.bounds
        and a.outside_is_wall == b.outside_is_wall
        and a.tiles == b.tiles
        and np.array_equal(a.walls, b.walls)
        and np.array_equal(a.starts, b.starts)
    )


def test_mazes(sections: Mapping[str, Settings]) -> list[tuple[str, str]]:
    """``(setting, maze name)`` of every maze a test of the run uses: ``[tests] maze`` and
    ``heldout_maze``, ``[tests3] maze`` and ``heldout_maze``, where the run has them."""
    out = []
    for section in ("tests", "tests3"):
        if section in sections:
            s = sections[section]
            for key in ("maze", "heldout_maze"):
                out.append((f"[{section}] {key}", str(getattr(s, key))))
    return out


def check_not_test_mazes(
    names: Sequence[tuple[str, str]], sections: Mapping[str, Settings]
) -> None:
    """Refuse a validation maze that is a test maze: one a test setting names, or a generated
    maze of a family's test split (:func:`mbn.world.mazes.families.check_use`). ``names``:
    ``(where, maze name)`` of the validation mazes (each already checked by
    :func:`trial_maze`)."""
    from mbn.world.mazes import families
    from mbn.world.mazes.load import load_maze

    for where, name in names:
        generated = families.parse_name(name)
        if generated is not None:
            families.check_use(generated.seeds, "validation", where, generated.family)

    tests: list[tuple[str, str, Maze | None]] = []
    for setting, name in test_mazes(sections):
        try:
            tests.append((setting, name, load_maze(name)))
        except MbnInputError:  # refused where it is set, by the tests' own check
            tests.append((setting, name, None))
    for where, name in names:
        maze = load_maze(name)
        for setting, test, other in tests:
            if name == test or (other is not None and same_maze(maze, other)):
                raise MbnInputError(
                    f"{where}: {name!r} is a test maze ({setting}); a maze that validates "
                    "candidates during evolution must be one no test uses"
                )


def follower_connections(texts: Sequence[str], where: str) -> list[Connection]:
    """The connections ``texts`` (``'W[i,j]'``, ``'WE[i,k]'``, 0-based) of the followers'
    network, or one line ``where: ...``: one that does not parse or that the network (3 neurons,
    3 inputs) lacks, or one listed twice."""
    from mbn.networks.programmable import Connection

    out: list[Connection] = []
    for k, text in enumerate(texts):
        try:
            c = Connection.parse(text)
        except MbnInputError as exc:
            raise MbnInputError(f"{where}[{k}]: {exc}") from None
        limit = FOLLOWER_NEURONS if c.kind == "W" else FOLLOWER_INPUTS
        if c.i >= FOLLOWER_NEURONS or c.j >= limit:
            raise MbnInputError(
                f"{where}[{k}]: {c} is not a connection of the followers' network "
                f"({FOLLOWER_NEURONS} neurons, {FOLLOWER_INPUTS} inputs; 0-based: W[0..2,0..2], "
                "WE[0..2,0..2])"
            )
        if c in out:
            raise MbnInputError(f"{where}[{k}]: {c} is listed twice")
        out.append(c)
    return out


def mbn_tile_rules(sections: Mapping[str, Settings]) -> tuple[str, ...] | None:
    """The tile rules of the MBN the run tests in the ``[tests]`` mazes, or None where it tests
    none there: the paper's (right, left) where a PM is evolved (``[pm]``), the three-behaviour
    MBN's where it is (``[mbn3] tile_rules``)."""
    if "pm" in sections:
        return PAPER_TILE_RULES
    if "mbn3" in sections:
        mbn3: Any = sections["mbn3"]
        return tuple(mbn3.tile_rules)
    return None


def locate(where: Locator, section: str, key: str, index: int | None = None) -> str:
    """``where(section, key)``, with ``[index]`` for an item of a list."""
    return where(section, key) + (f"[{index}]" if index is not None else "")
