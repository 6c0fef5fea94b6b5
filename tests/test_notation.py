"""One notation for connections wherever a person reads one (``mbn.notation``): the paper's
1-based ``W_23``; the code's 0-based ``W[1,2]`` only beside it, where code is meant."""

from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import pytest

from mbn.experiments.stages.im import IMStage
from mbn.experiments.stages.lf import LFStage
from mbn.experiments.stages.lf_search import LFSearchStage
from mbn.networks.programmable import Connection
from mbn.notation import connection_name, connection_names, connection_with_code

SRC = Path(__file__).resolve().parents[1] / "src" / "mbn"

#: The code's 0-based form of a connection, as text.
CODE = re.compile(r"\bWE?\[\d+, ?\d+\]")


@pytest.mark.parametrize(
    ("code", "name"),
    [
        ("W[1,2]", "W_23"),  # neuron 3 -> neuron 2, the paper's LF change
        ("W[1,1]", "W_22"),
        ("WE[1,0]", "WE_21"),
        ("WE[1,1]", "WE_22"),
        ("W[0,0]", "W_11"),
        ("W[9,1]", "W_10,2"),  # past 9: no name reads two ways
        ("WE[0,10]", "WE_1,11"),
    ],
)
def test_a_connection_is_named_as_the_paper_writes_it(code, name):
    assert connection_name(code) == name
    assert connection_name(Connection.parse(code)) == name
    assert connection_with_code(code) == f"{name} (code {code})"


def test_the_name_is_the_networks_paper_name_below_ten_neurons():
    for kind in ("W", "WE"):
        for i in range(9):
            for j in range(9):
                c = Connection(kind, i, j)
                assert connection_name(c) == c.paper_name


def test_names_are_joined_in_order():
    assert connection_names(["W[1,2]", "WE[1,0]", "WE[1,1]"]) == "W_23, WE_21, WE_22"
    assert connection_names([]) == ""


def test_the_stage_lines_name_connections_in_the_papers_notation():
    chosen = ["W[1,2]", "WE[1,0]", "WE[1,1]"]
    lf = SimpleNamespace(connections=chosen, best_fitness=8.0, generations=20, validation=None)
    # the summaries read the stages' records: stand-ins with the fields they read
    lines = [
        LFSearchStage().summary(SimpleNamespace(chosen=chosen)),
        IMStage().summary(SimpleNamespace(connections=chosen, neurons=21)),
        LFStage().summary(lf),
    ]
    for line in lines:
        assert "W_23, WE_21, WE_22" in line, line
        assert not CODE.search(line), line


def test_no_text_a_person_reads_is_made_from_a_connection_but_by_mbn_notation():
    """``Connection.paper_name`` and ``str(connection)`` in an f-string are the code's; every
    module outside ``mbn.networks`` and ``mbn.controllers`` (which write files) names a
    connection through ``mbn.notation``."""
    offenders = []
    for path in SRC.rglob("*.py"):
        rel = path.relative_to(SRC).as_posix()
        if rel.startswith(("networks/", "controllers/")) or rel == "notation.py":
            continue
        text = path.read_text()
        if ".paper_name" in text:
            offenders.append(f"{rel}: .paper_name")
        if re.search(r"\{', '\.join\([^)]*connections", text):
            offenders.append(f"{rel}: connections joined by hand")
    assert offenders == []
