"""How a connection is named wherever a person reads it: console lines, reports, claims, figures
and docs write the paper's 1-based notation (section 2: ``W_ij`` from neuron j to neuron i,
``WE_ik`` from external input k to neuron i), e.g. ``W_23``; the code's 0-based form
(``W[1,2]``, :class:`~mbn.networks.programmable.Connection`) is written only where code or a
file is meant (controller files, settings files, ``results.json``), and then beside the paper's
name (:func:`connection_with_code`).

:func:`connection_name` is the one place that turns a connection into its name.
"""

from __future__ import annotations

from collections.abc import Iterable

from mbn.networks.programmable import Connection

__all__ = ["connection_name", "connection_names", "connection_with_code"]


def _connection(connection: Connection | str) -> Connection:
    return Connection.parse(connection) if isinstance(connection, str) else connection


def connection_name(connection: Connection | str) -> str:
    """The paper's 1-based name of a connection (a :class:`Connection` or its code text
    ``"W[i,j]"``, ``"WE[i,k]"``): ``W[1,2]`` is ``W_23`` (neuron 3 -> neuron 2), ``WE[1,0]`` is
    ``WE_21``. An index past 9 is set off by a comma (``W_10,2``), so that no name reads two
    ways."""
    c = _connection(connection)
    i, j = c.i + 1, c.j + 1
    return f"{c.kind}_{i}{',' if max(i, j) > 9 else ''}{j}"


def connection_names(connections: Iterable[Connection | str]) -> str:
    """The paper's names of connections, in order, separated by commas: ``W_23, WE_21, WE_22``."""
    return ", ".join(connection_name(c) for c in connections)


def connection_with_code(connection: Connection | str) -> str:
    """The paper's name with the code's 0-based form beside it, where code is meant:
    ``W_23 (code W[1,2])``."""
    c = _connection(connection)
    return f"{connection_name(c)} (code {c})"
