"""Controller kinds: what a kind of controller must provide to be saved, loaded, evaluated, drawn
and evolved, and the one registry of kinds (``docs/architecture.md``, "Adding a controller
kind").

A kind is a :class:`ControllerKind` registered by :func:`register_controller_kind`. ``mbn``'s
kinds (``mbn.controller.ctrnn``, ``mbn.controller.interpreter``, ``mbn.controller.mbn`` and the
MBN's baselines ``mbn.controller.switched``, :mod:`mbn.controllers.builtin`) are registered so
too, and the codec and the loader know no other way to a kind than this registry:

* **saved and loaded**: :meth:`ControllerKind.to_dict` gives the fields of a spec's file after the
  header the codec writes (``kind``, ``format_version``, ``mbn_version``, ``provenance``);
  :meth:`ControllerKind.from_dict` reads the whole object back (the codec has checked its
  ``kind`` and ``format_version``), refusing anything wrong in one line naming ``where``
  (:func:`check_body` checks the fields, the header's included);
* **evaluated**: :meth:`ControllerKind.runner` makes a spec a :class:`Runner`: a controller
  ``(state, observation) -> (state, (v, w))`` for one robot, its batched initial state, the
  sensors it reads, its robot step, and what the rollout needs besides (a camera, programs...).
  The rollout maps the controller over a batch (:func:`mbn.world.rollout.map_controller`) and
  compiles it once per controller object: give the same object for the same settings
  (:func:`mbn.memo.memoized` makes a factory do that);
* **drawn**: :meth:`ControllerKind.weights` names the arrays a picture of it shows
  (:func:`mbn.viz.controllers.draw_controller`); a kind that names none is drawn as a panel of
  text (its kind and its spec's fields). Its episodes are drawn as any controller's, from the
  rollout (:mod:`mbn.viz.episodes`);
* **evolved**: :meth:`ControllerKind.genes` and :meth:`ControllerKind.with_genes` map a spec to a
  genome and a genome to a spec (the template with those genes), which
  :func:`mbn.experiments.evolve.kind_fitness` turns into a fitness for DE
  (:func:`mbn.experiments.evolve.start`, :func:`mbn.experiments.evolve.generation`).

A kind kept outside ``mbn`` is registered by the code that defines it, or by an installed
package under the entry-point group :data:`ENTRY_POINT_GROUP` (name: the kind, value:
``package.module:ATTRIBUTE`` of the :class:`ControllerKind`), read the first time a kind is not
found.
"""

from __future__ import annotations

import re
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from mbn.errors import MbnInputError
from mbn.io import check_fields
from mbn.world.engine import CameraConfig
from mbn.world.sensors import NoiseConfig, SensorConfig

__all__ = [
    "ENTRY_POINT_GROUP",
    "HEADER_FIELDS",
    "OPTIONAL_HEADER_FIELDS",
    "ControllerKind",
    "Runner",
    "check_body",
    "controller_kind",
    "kind_of",
    "register_controller_kind",
    "registered_kinds",
    "unregister_controller_kind",
]

#: The entry-point group under which installed packages register controller kinds.
ENTRY_POINT_GROUP = "mbn.controller_kinds"
#: The header fields every controller file has (written by the codec, checked before a kind reads).
HEADER_FIELDS: tuple[str, ...] = ("kind", "format_version")
#: The header fields the codec writes that a reader may do without.
OPTIONAL_HEADER_FIELDS: tuple[str, ...] = ("mbn_version", "provenance")

#: A kind's name: lower-case words joined by dots, at least two (``my_lab.controller.linear``).
_NAME = re.compile(r"^[a-z][a-z0-9_]*(\.[a-z][a-z0-9_-]*)+$")
#: Names under ``mbn.`` are ``mbn``'s own.
_OWN = "mbn."

#: A controller for one robot: ``(state, observation) -> (state, (v, w))``.
Controller = Callable[[Any, Any], tuple[Any, Any]]


@dataclass(frozen=True, eq=False)
class Runner:
    """A spec made ready to run in the batched rollout (:meth:`ControllerKind.runner`).

    Attributes:
        controller: ``(state, obs) -> (state, (v, w))`` for one robot, JAX-traceable: ``obs`` is a
            :class:`mbn.world.rollout.Observation` (``inputs``: the paper's I1..I3, ``S``: the
            normalised sonars, ``camera``, ``tile``, ``t``, ``key``...), ``v`` (m/s) and ``w``
            (rad/s, positive turns left) scalars. The same object for the same settings: the
            rollout is compiled once per controller object.
        initial_state: ``n ->`` the initial state of ``n`` robots, a pytree whose leaves have
            the batch as leading axis, except parts wrapped in :class:`mbn.world.rollout.Shared`
            (held once for the batch, e.g. the weights; the controller sees them unwrapped and
            returns them unchanged). Where the states of several specs are joined (a population
            evaluated in one rollout, :func:`mbn.world.rollout.concatenate_states`), shared
            parts that differ get a batch axis.
        sensors: the sonars to cast and their normalisation.
        dt: the robot step (s).
        camera: the camera it reads, or None (no camera: ``obs.camera`` reads 0).
        programs: its named programs (none for most kinds).
        program: the program in use, or None.
        behavior: the behaviour its file declares, or None.
        initial_rule: the rule it follows before its first tile, or None.
        tile_rules: the rule a tile of 1, 2, ... colours puts in force, for a controller that
            reads the tiles; else None.
        network_steps: network steps it takes each robot step (bounds a trial's cost,
            :func:`mbn.controllers.load.check_trial_length`).
    """

    controller: Controller
    initial_state: Callable[[int], Any]
    sensors: SensorConfig
    dt: float
    camera: CameraConfig | None = None
    programs: Mapping[str, tuple[float, ...]] = field(default_factory=dict)
    program: str | None = None
    behavior: str | None = None
    initial_rule: str | None = None
    tile_rules: tuple[str, ...] | None = None
    network_steps: int = 1


class ControllerKind(ABC):
    """What a kind of controller provides (module docstring). Subclass it, set :attr:`name` and
    :attr:`spec_type`, write the three abstract methods, and register an instance with
    :func:`register_controller_kind`; drawing and evolving are optional.

    Attributes:
        name: the ``kind`` its files carry, lower-case words joined by dots
            (``my_lab.controller.linear``); names under ``mbn.`` are ``mbn``'s.
        spec_type: the class of its specs (a frozen dataclass, validated on construction, as
            :mod:`mbn.controllers.spec`'s); a spec is this kind's when it is an instance.
    """

    name: str
    spec_type: type

    @abstractmethod
    def to_dict(self, spec: Any) -> dict[str, Any]:
        """The JSON fields of ``spec``'s file after the header (JSON values only: the codec
        writes ``{**header, **to_dict(spec)}`` and checks that it reads back)."""

    @abstractmethod
    def from_dict(self, data: dict[str, Any], where: str) -> Any:
        """The spec of a file's JSON object ``data`` (its header checked by the codec), or
        :class:`~mbn.errors.MbnInputError` in one line starting with ``where``."""

    @abstractmethod
    def runner(
        self, spec: Any, program: str | None, noise: NoiseConfig | None, where: str
    ) -> Runner:
        """``spec`` ready to run (:class:`Runner`). ``program``: the program asked for (refuse one
        the kind has not, naming ``where``); ``noise``: the noise it runs under (None or all
        zero: none; a kind may leave its own channels, ``neuron_std`` and ``program_std``,
        unused: the world's channels are the rollout's)."""

    def step_beyond_limit(self, spec: Any, where: str) -> str | None:
        """Why ``spec``'s integration step is beyond its stability limit (one line naming
        ``where``), or None where it is within or the kind has no such limit (the default)."""
        return None

    def weights(self, spec: Any) -> Mapping[str, np.ndarray]:
        """The arrays a picture of ``spec`` shows, by name (1-D or 2-D each). None by default:
        the picture is then a panel of text."""
        return {}

    def genes(self, spec: Any) -> np.ndarray:
        """The genome of ``spec`` (1-D): what evolution changes of it. Its length is the genome's
        size; :meth:`with_genes` of these genes gives ``spec`` back."""
        raise MbnInputError(f"controller kind {self.name} cannot be evolved: it defines no genes")

    def with_genes(self, spec: Any, genes: np.ndarray) -> Any:
        """``spec`` (the template) with the genome ``genes`` in place of its own: a new spec,
        validated. Everything the runner's controller function depends on (its settings)
        stays the template's, so that a population runs as one batch."""
        raise MbnInputError(f"controller kind {self.name} cannot be evolved: it defines no genes")


_KINDS: dict[str, ControllerKind] = {}
_PLUGINS_READ = False


def register_controller_kind(kind: ControllerKind) -> ControllerKind:
    """Register ``kind`` (a :class:`ControllerKind`): files of kind ``kind.name`` are read, and
    specs of ``kind.spec_type`` written, run, drawn and evolved through it. A name registered
    already, a name under ``mbn.`` (``mbn``'s own) and a spec class another kind has are
    refused. Returns ``kind``."""
    if not isinstance(kind, ControllerKind):
        raise MbnInputError(
            f"a controller kind must be a ControllerKind, got {type(kind).__name__}"
        )
    name = getattr(kind, "name", None)
    if not isinstance(name, str) or not _NAME.match(name):
        raise MbnInputError(
            f"controller kind name {name!r}: lower-case words joined by dots "
            "(my_lab.controller.linear)"
        )
    if name.startswith(_OWN) and not type(kind).__module__.startswith(_OWN):
        raise MbnInputError(f"controller kind {name!r}: names under {_OWN!r} are mbn's own")
    spec_type = getattr(kind, "spec_type", None)
    if not isinstance(spec_type, type):
        raise MbnInputError(f"controller kind {name}: spec_type must be a class, got {spec_type!r}")
    if name in _KINDS:
        raise MbnInputError(f"controller kind {name!r} is registered already")
    for other in _KINDS.values():
        if issubclass(spec_type, other.spec_type) or issubclass(other.spec_type, spec_type):
            raise MbnInputError(
                f"controller kind {name}: its specs ({spec_type.__name__}) would be taken for "
                f"those of {other.name} ({other.spec_type.__name__})"
            )
    _KINDS[name] = kind
    return kind


def unregister_controller_kind(name: str) -> ControllerKind:
    """Remove the kind ``name`` from the registry (one registered outside ``mbn``) and return
    it: its files are no longer read."""
    kind = _KINDS.get(name)
    if kind is None:
        raise MbnInputError(f"controller kind {name!r} is not registered")
    if type(kind).__module__.startswith(_OWN):
        raise MbnInputError(f"controller kind {name!r} is mbn's own: it stays registered")
    del _KINDS[name]
    return kind


def registered_kinds() -> Mapping[str, ControllerKind]:
    """Every registered kind by name, in the order registered (``mbn``'s own first: the paper's
    three, then ``mbn.controller.switched``)."""
    return MappingProxyType(_KINDS)


def controller_kind(name: str) -> ControllerKind | None:
    """The kind registered as ``name`` (an installed package's, read on the first miss), or
    None."""
    if name not in _KINDS:
        _read_plugins()
    return _KINDS.get(name)


def kind_of(spec: Any) -> ControllerKind | None:
    """The registered kind whose specs ``spec`` is one of, or None."""
    for _ in range(2):
        for kind in _KINDS.values():
            if isinstance(spec, kind.spec_type):
                return kind
        if not _read_plugins():
            break
    return None


def check_body(
    data: Mapping[str, Any], where: str, required: Sequence[str], optional: Iterable[str] = ()
) -> None:
    """Refuse a controller file that lacks one of the fields ``required`` or has one that is
    neither those, nor ``optional``, nor a header field (:data:`HEADER_FIELDS`,
    :data:`OPTIONAL_HEADER_FIELDS`), in one line naming ``where``."""
    check_fields(data, where, [*HEADER_FIELDS, *required], [*OPTIONAL_HEADER_FIELDS, *optional])


def _read_plugins() -> bool:
    """Register the kinds installed packages name under :data:`ENTRY_POINT_GROUP` (once per
    process; a name registered already is left as it is). Whether this call read them."""
    global _PLUGINS_READ
    if _PLUGINS_READ:
        return False
    _PLUGINS_READ = True
    from importlib.metadata import entry_points

    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if ep.name in _KINDS:
            continue
        try:
            kind = ep.load()
        except Exception as exc:  # the package's module failed: say which and why
            raise MbnInputError(
                f"controller kind {ep.name}: loading {ep.value} failed: {exc!r}"
            ) from exc
        if getattr(kind, "name", None) != ep.name:
            raise MbnInputError(
                f"controller kind {ep.name}: {ep.value} is not a ControllerKind of that name"
            )
        register_controller_kind(kind)
    return True
