"""The one list of experiments: what ``mbn run``, ``mbn reproduce``, ``mbn sweep`` (its seeds'
runs, targets and report), ``--reuse`` and ``--help`` know.

An experiment is registered by one line, with the place of its
:class:`~mbn.experiments.pipeline.experiment.Experiment` as ``"package.module:ATTRIBUTE"``
(nothing is imported until a run needs it, as Gymnasium's ``register(id, entry_point=...)``)::

    register("new-behaviours", "mbn.experiments.behaviours:NEW_BEHAVIOURS", help="...",
             sweep="mbn.experiments.behaviours.sweep:NEW_BEHAVIOURS_SPEC")

An experiment kept outside ``mbn`` runs without registering it, by its reference wherever a name
goes (``mbn run my_pkg.my_module:EXPERIMENT``, ``mbn run path/to/file.py:EXPERIMENT``, ``mbn sweep
--experiment ...``); an installed package registers its experiments under the entry-point group
:data:`ENTRY_POINT_GROUP` (the entry point's name is the experiment's, its value the reference)::

    [project.entry-points."mbn.experiments"]
    my-experiment = "my_pkg.my_module:EXPERIMENT"

``sweep`` names the experiment's view for ``mbn sweep`` (a
:class:`~mbn.experiments.sweep.specs.SweepSpec`: per-run targets, the tests its report tabulates,
the DE curves it draws); without one a sweep reports every test the runs recorded, with no
per-run target (:func:`~mbn.experiments.sweep.specs.plain_spec`).
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import re
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from mbn.errors import MbnInputError

if TYPE_CHECKING:
    from mbn.experiments.pipeline.experiment import Experiment

__all__ = [
    "ENTRY_POINT_GROUP",
    "Registration",
    "find",
    "is_reference",
    "load_object",
    "of_kind",
    "register",
    "registered",
]

#: The entry-point group under which installed packages register experiments.
ENTRY_POINT_GROUP = "mbn.experiments"

_NAME = re.compile(r"^[a-z][a-z0-9]*(-[a-z0-9]+)*$")
_REFERENCE = re.compile(r"^(?P<where>[^:]+):(?P<attr>[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_]\w*)*)$")


@dataclass(frozen=True)
class Registration:
    """One experiment as the command line knows it.

    Attributes:
        name: its name (``mbn run NAME``, ``--experiment NAME``); for an experiment run by its
            reference, the reference.
        entry_point: where its :class:`Experiment` is, ``"package.module:ATTRIBUTE"`` or
            ``"/path/to/file.py:ATTRIBUTE"``.
        help: one line for ``--help``.
        sweep: where its sweep's view is (a ``SweepSpec``), or None (every recorded test, no
            per-run target).
        command: the command one run is, for reports (``mbn reproduce``; default ``mbn run
            NAME``).
    """

    name: str
    entry_point: str
    help: str = ""
    sweep: str | None = None
    command: str = ""

    def load(self) -> Experiment:
        """The experiment (its module imported now)."""
        from mbn.experiments.pipeline.experiment import Experiment

        value = load_object(self.entry_point)
        if not isinstance(value, Experiment):
            raise MbnInputError(
                f"experiment {self.name}: {self.entry_point} is a {type(value).__name__}, not an "
                "mbn Experiment (mbn.experiments.pipeline.experiment.Experiment)"
            )
        return value

    @property
    def run_command(self) -> str:
        return self.command or f"mbn run {self.name}"


_BUILTIN: dict[str, Registration] = {}
_PLUGINS: dict[str, Registration] | None = None


def register(
    name: str,
    entry_point: str,
    *,
    help: str = "",
    sweep: str | None = None,
    command: str = "",
) -> Registration:
    """Register an experiment under ``name`` (lower case words joined by ``-``): its
    :class:`Experiment` is at ``entry_point`` (``"package.module:ATTRIBUTE"``), imported only
    when a run needs it. A name registered twice is refused."""
    if not _NAME.match(name):
        raise ValueError(f"experiment name {name!r}: lower-case words joined by '-' (my-rule)")
    _check_reference(entry_point, f"experiment {name}")
    if sweep is not None:
        _check_reference(sweep, f"experiment {name}: sweep")
    if name in _BUILTIN:
        raise ValueError(f"experiment {name!r} is registered already")
    registration = Registration(name, entry_point, help, sweep, command)
    _BUILTIN[name] = registration
    return registration


def registered() -> Mapping[str, Registration]:
    """Every registered experiment by name: ``mbn``'s own, then those of installed packages
    (entry-point group :data:`ENTRY_POINT_GROUP`; a name ``mbn`` has already is left out)."""
    return MappingProxyType({**_BUILTIN, **_plugins()})


def is_reference(text: str) -> bool:
    """Whether ``text`` is an experiment's reference (``module:ATTR``, ``file.py:ATTR``)."""
    return _REFERENCE.match(text) is not None


def find(name: str) -> Registration:
    """The registered experiment ``name``, or the one at the reference ``name``
    (``package.module:ATTRIBUTE`` or ``path/to/file.py:ATTRIBUTE``, a relative path resolved
    here); anything else is refused in one line listing the registered names."""
    found = registered().get(name)
    if found is not None:
        return found
    match = _REFERENCE.match(name)
    if match is None:
        known = ", ".join(sorted(registered()))
        raise MbnInputError(
            f"experiment {name!r}: not a registered experiment ({known}) nor a reference "
            "(package.module:ATTRIBUTE or path/to/file.py:ATTRIBUTE)"
        )
    where = match["where"]
    if where.endswith(".py"):
        path = Path(where).expanduser()
        if not path.is_file():
            raise MbnInputError(f"experiment {name}: no file {where}")
        reference = f"{path.resolve()}:{match['attr']}"
        return Registration(reference, reference)
    return Registration(name, name)


def of_kind(kind: str, also: Experiment | None = None) -> Experiment | None:
    """The experiment whose runs record ``kind`` in their ``run.json`` (``mbn.reproduce``):
    ``also`` if it is that one, else a registered one; None if none (how ``--reuse`` finds the
    stages of a source run)."""
    if also is not None and also.kind == kind:
        return also
    for registration in registered().values():
        try:
            experiment = registration.load()
        except MbnInputError:
            continue  # an installed package's broken entry point hides no other experiment
        if experiment.kind == kind:
            return experiment
    return None


def load_object(reference: str) -> Any:
    """The object at ``package.module:ATTRIBUTE`` or ``/path/to/file.py:ATTRIBUTE``; a module
    that cannot be imported or an attribute it lacks is refused in one line."""
    match = _REFERENCE.match(reference)
    if match is None:
        raise MbnInputError(f"{reference}: not a reference (package.module:ATTRIBUTE)")
    where, attr = match["where"], match["attr"]
    try:
        module = _import_file(Path(where)) if where.endswith(".py") else _import(where)
    except MbnInputError:
        raise
    except Exception as exc:  # the user's module failed while importing: say which and why
        raise MbnInputError(f"{reference}: importing {where} failed: {exc!r}") from exc
    value: Any = module
    for part in attr.split("."):
        if not hasattr(value, part):
            raise MbnInputError(f"{reference}: {where} has no {attr}")
        value = getattr(value, part)
    return value


def _import(module: str) -> Any:
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name is not None and (module == exc.name or module.startswith(exc.name + ".")):
            raise MbnInputError(f"{module}: no module of that name (is it installed?)") from exc
        raise


def _import_file(path: Path) -> Any:
    """The module of a Python file, imported once per process under a name made from its
    resolved path (so that a sweep's workers and a resumed run find the same one)."""
    path = path.expanduser().resolve()
    if not path.is_file():
        raise MbnInputError(f"{path}: no such file")
    digest = hashlib.sha256(str(path).encode()).hexdigest()[:12]
    stem = re.sub(r"\W", "_", path.stem)
    name = f"mbn_user_{stem}_{digest}"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise MbnInputError(f"{path}: not a Python module")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module


def _check_reference(reference: str, what: str) -> None:
    if not _REFERENCE.match(reference):
        raise ValueError(f"{what}: {reference!r} is not 'package.module:ATTRIBUTE'")


def _plugins() -> dict[str, Registration]:
    """The experiments installed packages register (read once per process)."""
    global _PLUGINS
    if _PLUGINS is None:
        from importlib.metadata import entry_points

        found: dict[str, Registration] = {}
        for ep in entry_points(group=ENTRY_POINT_GROUP):
            if ep.name in _BUILTIN or not _NAME.match(ep.name) or not is_reference(ep.value):
                continue
            dist = getattr(ep, "dist", None)
            origin = f" (from {dist.name})" if dist is not None else ""
            found[ep.name] = Registration(ep.name, ep.value, f"an installed experiment{origin}")
        _PLUGINS = found
    return _PLUGINS


# --- mbn's experiments: one line each ----------------------------------------------------------

register(
    "reproduce",
    "mbn.experiments.reproduce:REPRODUCE",
    help="the paper's experiment: RF, LF, the interpreter, the program module and the MBN, "
    "with the paper's tests (docs/reproduce.md; also `mbn reproduce`)",
    sweep="mbn.experiments.reproduce.sweep:REPRODUCE_SPEC",
    command="mbn reproduce",
)
register(
    "new-behaviours",
    "mbn.experiments.behaviours:NEW_BEHAVIOURS",
    help="a fully programmable interpreter of the run's RF, and new behaviours by its programs "
    "alone (docs/behaviours.md)",
    sweep="mbn.experiments.behaviours.sweep:NEW_BEHAVIOURS_SPEC",
)
register(
    "switch",
    "mbn.experiments.switch:SWITCH",
    help="the switch between programs: the interpreter running mixtures of two programs, and "
    "the equilibria of the networks they decode to (docs/switch.md)",
    sweep="mbn.experiments.switch.sweep:SWITCH_SPEC",
)
register(
    "scaling",
    "mbn.experiments.scaling:SCALING",
    help="MBNs of 2 to 6 behaviours on one fixed interpreter, each grown from the one before: "
    "success on each family's test split, forgetting, the program module's code error, the "
    "cost of each behaviour (docs/scaling.md)",
    sweep="mbn.experiments.scaling.sweep:SCALING_SPEC",
)
register(
    "noise",
    "mbn.experiments.noise:NOISE",
    help="the reproduction's controllers under each channel of the noise model, level by level "
    "(docs/noise.md)",
    sweep="mbn.experiments.noise.sweep:NOISE_SPEC",
)
register(
    "ablations",
    "mbn.experiments.ablations:ABLATIONS",
    help="the MBN with parts of its program path changed: wrong or frozen program, exact "
    "products, the multipliers' time constant and size (docs/ablations.md)",
    sweep="mbn.experiments.ablations.sweep:ABLATIONS_SPEC",
)
register(
    "programs-vs-dynamics",
    "mbn.experiments.contest:PROGRAMS_VS_DYNAMICS",
    help="new rules learned by program search on the fixed interpreter, by a new CTRNN and by "
    "RF re-evolved, and the three-behaviour task by the MBN and by a monolithic CTRNN, same DE "
    "and budget: evaluations to success (docs/contest.md; over seeds with mbn sweep)",
    sweep="mbn.experiments.contest.sweep:CONTEST_SPEC",
)
