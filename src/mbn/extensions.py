"""A lab's own modules, imported before a command runs, so that what they register (a rule, a
maze family, a fitness, a sensor, a maze format, a controller kind) is known to every command
(``mbn evaluate --rule my_rule``, ``mbn mazes generate my_family``), not only to the experiment
that imports them.

Two ways to name them, both read by :func:`load` (the command line calls it once, before
parsing; a sweep's seed task calls it again in its worker process):

- an installed package's entry points in the group :data:`ENTRY_POINT_GROUP`, whose values are
  modules (``[project.entry-points."mbn.extensions"]`` ``my_rules = "my_lab.rules"``);
- the environment variable :data:`VARIABLE`, modules separated by commas
  (``MBN_EXTENSIONS=my_rules,my_lab.families``), for modules that are not installed (on
  ``PYTHONPATH`` or in the current folder).

A module that cannot be imported is refused in one line naming it and where it was named
(:class:`~mbn.errors.MbnInputError`: exit status 2 at the command line).
"""

from __future__ import annotations

import importlib
import os
import re
import sys
from collections.abc import Mapping

from mbn.errors import MbnInputError

__all__ = ["ENTRY_POINT_GROUP", "VARIABLE", "load", "named"]

#: The entry-point group of installed packages' extension modules.
ENTRY_POINT_GROUP = "mbn.extensions"
#: The environment variable naming extension modules (comma-separated).
VARIABLE = "MBN_EXTENSIONS"

_MODULE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")
_loaded: set[str] = set()


def named(env: Mapping[str, str] | None = None) -> list[tuple[str, str]]:
    """``(module, where it was named)`` of every extension: the entry points first (in the
    order the installed packages give them), then :data:`VARIABLE`'s, each once."""
    env = os.environ if env is None else env
    out: list[tuple[str, str]] = []
    from importlib.metadata import entry_points

    for ep in entry_points(group=ENTRY_POINT_GROUP):
        dist = getattr(ep, "dist", None)
        origin = f" of {dist.name}" if dist is not None else ""
        out.append((ep.value.split(":")[0].strip(), f"entry point {ep.name!r}{origin}"))
    for part in env.get(VARIABLE, "").split(","):
        if part.strip():
            out.append((part.strip(), VARIABLE))
    first: dict[str, str] = {}
    for module, where in out:
        first.setdefault(module, where)
    return list(first.items())


def load(env: Mapping[str, str] | None = None) -> list[str]:
    """Import every extension module not imported yet; the modules imported now. The current
    folder is searched as ``python -c`` would (a module beside one's configs)."""
    done = []
    for module, where in named(env):
        if module in _loaded:
            continue
        if not _MODULE.match(module):
            raise MbnInputError(f"{where}: {module!r} is not a module name (e.g. my_lab.rules)")
        if "" not in sys.path and os.getcwd() not in sys.path:
            sys.path.append(os.getcwd())
        try:
            importlib.import_module(module)
        except ImportError as exc:
            raise MbnInputError(f"{where}: cannot import {module!r} ({exc})") from None
        _loaded.add(module)
        done.append(module)
    return done
