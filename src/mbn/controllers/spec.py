"""What a controller file holds, as Python objects validated on construction.

Three kinds (``docs/controllers.md``):

* :class:`CTRNNControllerSpec` (``"mbn.controller.ctrnn"``): a CTRNN fed the paper's inputs
  I1..I3; optional ``behavior``; with ``tile_rules``, also one camera input per tile kind (a
  monolithic controller of several behaviours, ``docs/contest.md``).
* :class:`InterpreterControllerSpec` (``"mbn.controller.interpreter"``): the fixed-weight
  interpreter of :mod:`mbn.networks.programmable` and named ``programs``.
* :class:`MBNControllerSpec` (``"mbn.controller.mbn"``): the Multiple Behavior Network: an
  interpreter spec plus the program module, a CTRNN whose two inputs encode the camera and whose
  ``program_neurons``' firing rates are the program.

and the MBN's two baselines, one kind:

* :class:`SwitchedControllerSpec` (``"mbn.controller.switched"``): one plain CTRNN follower per
  rule, the rule in force latched from the tiles the camera sees as the MBN reads them; in
  ``"swap"`` mode one state whose weights are swapped to the network of the rule in force (the
  oracle: the MBN without the cost of its multipliers), in ``"gate"`` mode the followers run side
  by side and the one of the rule in force drives. :func:`decoded_networks` gives the network each
  program of an interpreter encodes, and :func:`switched_from_mbn` the baseline of an MBN.

Each spec also carries the sensors (:class:`~mbn.world.sensors.SensorConfig`), the motor mapping
(:class:`~mbn.control.ctrnn.MotorMap`), ``dt``, ``substeps``, ``method`` and free ``metadata``.
The JSON form is :mod:`mbn.controllers.codec`; making a spec run is :mod:`mbn.controllers.load`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import jax.numpy as jnp
import numpy as np

from mbn.control.ctrnn import NETWORK_SUBSTEPS, MotorMap
from mbn.control.switched import MODES
from mbn.errors import MbnInputError
from mbn.networks.ctrnn import CTRNN, make_ctrnn
from mbn.networks.programmable import Connection, Interpreter
from mbn.world.engine import CameraConfig
from mbn.world.mazes.model import TILE_COLORS
from mbn.world.rules import parse_rule
from mbn.world.sensors import PAPER_SONARS, SensorConfig

__all__ = [
    "FORMAT_VERSION",
    "KINDS",
    "KIND_CTRNN",
    "KIND_INTERPRETER",
    "KIND_MBN",
    "KIND_SWITCHED",
    "MAX_DT",
    "MAX_SUBSTEPS",
    "MIN_DT",
    "MULTIPLIER_KIND",
    "NUM_INPUTS",
    "PM_INPUTS",
    "SIMULATIONS",
    "CTRNNControllerSpec",
    "ControllerSpec",
    "InterpreterControllerSpec",
    "MBNControllerSpec",
    "PMInitial",
    "SwitchedControllerSpec",
    "decoded_networks",
    "switched_from_mbn",
]

KIND_CTRNN = "mbn.controller.ctrnn"
KIND_INTERPRETER = "mbn.controller.interpreter"
KIND_MBN = "mbn.controller.mbn"
#: The kind of the MBN's baselines: followers switched by the tiles
#: (:class:`SwitchedControllerSpec`).
KIND_SWITCHED = "mbn.controller.switched"
#: The paper's controller kinds, registered first and in this order (error messages list them
#: so, then the others: :data:`KIND_SWITCHED`, and kinds registered outside ``mbn``).
KINDS: tuple[str, ...] = (KIND_CTRNN, KIND_INTERPRETER, KIND_MBN)
FORMAT_VERSION = 1
#: Kind of a multiplier file (:mod:`mbn.networks.multiplier`), recognised to give a clear error.
MULTIPLIER_KIND = "mbn.multiplier"
#: Number of data inputs every controller reads: the paper's I1..I3 (eq. 3).
NUM_INPUTS = 3
#: Inputs of the paper's program module: a one-colour tile in view, a two-colour tile in view
#: (an MBN of more tile kinds has one input per kind, ``MBNControllerSpec.tile_rules``).
PM_INPUTS = 2

# --------------------------------------------------------------------------------------------
# Specs: what a file holds, as Python objects (validated on construction)
# --------------------------------------------------------------------------------------------


#: The longest robot step a controller may ask for (s): Stage's default is 0.1 s; beyond a second
#: the sonars would sample a corridor too coarsely to follow it.
MAX_DT = 1.0
#: The shortest robot step a controller may ask for (s): a trial of the paper's protocol (90 s in
#: fig4) is then 90 000 robot steps, well within :data:`mbn.controllers.load.MAX_TRIAL_STEPS`;
#: shorter steps make a trial of a few minutes take hours (1e-7 s: 9e8 steps), or more steps
#: than a rollout can count (1e-300 s).
MIN_DT = 1e-3
#: The most network steps per robot step (each costs a full integration step of the network).
MAX_SUBSTEPS = 10_000


def _check_run_settings(dt: float, substeps: int, method: str) -> None:
    if isinstance(dt, bool) or not isinstance(dt, (int, float)) or not (MIN_DT <= dt <= MAX_DT):
        raise MbnInputError(f"dt must be a number in [{MIN_DT:g}, {MAX_DT:g}] s, got {dt!r}")
    if (
        isinstance(substeps, bool)
        or not isinstance(substeps, int)
        or not 1 <= substeps <= MAX_SUBSTEPS
    ):
        raise MbnInputError(f"substeps must be an integer in [1, {MAX_SUBSTEPS}], got {substeps!r}")
    if method not in ("euler", "rk4"):
        raise MbnInputError(f"method must be euler or rk4, got {method!r}")


def _check_sensors(sensors: SensorConfig) -> None:
    if not isinstance(sensors, SensorConfig):
        raise MbnInputError(f"sensors must be a SensorConfig, got {type(sensors).__name__}")
    missing = [s for s in PAPER_SONARS if s not in sensors.sonars]
    if missing:
        raise MbnInputError(
            f"sensors.sonars must include the paper's 10 sonars {list(PAPER_SONARS)} (the "
            f"controller reads I1..I3 of eq. 3); missing {missing}"
        )


def _check_motor(motor: MotorMap, neurons: int, what: str) -> None:
    if not isinstance(motor, MotorMap):
        raise MbnInputError(f"motor must be a MotorMap, got {type(motor).__name__}")
    for name in ("speed_neuron", "turn_neuron"):
        index = getattr(motor, name)
        if not 0 <= index < neurons:
            raise MbnInputError(
                f"motor.{name} {index} is not one of the {neurons} neurons of {what} "
                f"(0..{neurons - 1})"
            )


def _check_single(net: CTRNN, what: str) -> None:
    if not isinstance(net, CTRNN):
        raise MbnInputError(f"{what} must be a CTRNN, got {type(net).__name__}")
    if net.W.ndim != 2:
        raise MbnInputError(f"{what}: expected one network, got W of shape {tuple(net.W.shape)}")


def _check_metadata(metadata: Mapping[str, Any]) -> None:
    if not isinstance(metadata, Mapping) or not all(isinstance(k, str) for k in metadata):
        raise MbnInputError("metadata must be an object with string keys")


@dataclass(frozen=True, eq=False)
class CTRNNControllerSpec:
    """A plain CTRNN controller: the network reads I1..I3, its motor neurons drive the robot.

    Attributes:
        net: the network (unbatched, 3 inputs; 3 + ``len(tile_rules)`` with tile rules).
        sensors: the sonars cast and their normalisation (must include the paper's 10).
        motor: which neurons set ``v`` and ``w``.
        dt: robot step (s), in [:data:`MIN_DT`, :data:`MAX_DT`].
        substeps: network steps per robot step.
        method: "euler" or "rk4".
        behavior: what it was made for, "right" or "left" (or None).
        metadata: free JSON-serialisable information (how it was made, scores, ...).
        tile_rules: None (the paper's followers: I1..I3 only), or the rule a tile of 1, 2, ...
            colours puts in force: the network then also reads the camera, ``[camera == 1,
            camera == 2, ...]`` after I1..I3, and must keep the rule of the last tile itself
            (a monolithic controller of several behaviours, the usual alternative to an MBN).
        camera: the blob-finding camera it reads (with ``tile_rules`` only).
        kind: the file kind (class constant).
    """

    kind: ClassVar[str] = KIND_CTRNN
    net: CTRNN
    sensors: SensorConfig = field(default_factory=SensorConfig)
    motor: MotorMap = field(default_factory=MotorMap)
    dt: float = 0.1
    substeps: int = NETWORK_SUBSTEPS
    method: str = "euler"
    behavior: str | None = None
    metadata: Mapping[str, Any] = field(default_factory=dict)
    tile_rules: tuple[str, ...] | None = None
    camera: CameraConfig = field(default_factory=CameraConfig)

    def __post_init__(self) -> None:
        _check_single(self.net, "network")
        if self.tile_rules is not None:
            object.__setattr__(self, "tile_rules", _tile_rules(self.tile_rules, "tile_rules"))
            if not isinstance(self.camera, CameraConfig):
                raise MbnInputError(
                    f"camera must be a CameraConfig, got {type(self.camera).__name__}"
                )
        if self.net.num_inputs != self.num_inputs:
            tiles = len(self.tile_rules or ())
            raise MbnInputError(
                f"network: a controller reads the paper's {NUM_INPUTS} inputs I1..I3"
                + (f" and {tiles} camera inputs (one per tile kind)" if tiles else "")
                + f", but WE has {self.net.num_inputs} columns"
            )
        _check_sensors(self.sensors)
        _check_motor(self.motor, self.net.num_neurons, "the network")
        _check_run_settings(self.dt, self.substeps, self.method)
        if self.behavior is not None:
            try:
                object.__setattr__(self, "behavior", parse_rule(self.behavior).name)
            except MbnInputError as exc:
                raise MbnInputError(f"behavior: {exc}") from None
        _check_metadata(self.metadata)
        object.__setattr__(self, "metadata", dict(self.metadata))

    @property
    def num_inputs(self) -> int:
        """The network's inputs: I1..I3, then one camera input per tile kind."""
        return NUM_INPUTS + len(self.tile_rules or ())


def _tile_rules(rules: Sequence[str], where: str) -> tuple[str, ...]:
    """Rule names, one per tile kind (1 to the kinds the camera sees), parsed."""
    try:
        names = tuple(parse_rule(r).name for r in rules)
    except MbnInputError as exc:
        raise MbnInputError(f"{where}: {exc}") from None
    if not 1 <= len(names) <= len(TILE_COLORS):
        raise MbnInputError(
            f"{where}: one rule per tile kind (1 to {len(TILE_COLORS)}), got {len(names)}"
        )
    return names


def _check_interpreter(interp: Interpreter) -> None:
    """Consistency of an :class:`Interpreter` (its layout, bounds and connections)."""
    if not isinstance(interp, Interpreter):
        raise MbnInputError(f"interpreter must be an Interpreter, got {type(interp).__name__}")
    _check_single(interp.net, "interpreter.net")
    k = len(interp.connections)
    if k < 1:
        raise MbnInputError("interpreter.connections: at least one programmable connection")
    if len(set(interp.connections)) != k:
        raise MbnInputError("interpreter.connections: a connection is listed twice")
    for name, value, low in (
        ("num_original", interp.num_original, 1),
        ("num_data_inputs", interp.num_data_inputs, 0),
        ("mul_size", interp.mul_size, 1),
        ("mul_output", interp.mul_output, 0),
    ):
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise MbnInputError(f"interpreter.{name} must be an integer >= {low}, got {value!r}")
    if interp.num_data_inputs != NUM_INPUTS:
        raise MbnInputError(
            f"interpreter.num_data_inputs: a controller reads the paper's {NUM_INPUTS} inputs "
            f"I1..I3, got {interp.num_data_inputs}"
        )
    if interp.mul_output >= interp.mul_size:
        raise MbnInputError(
            f"interpreter.mul_output {interp.mul_output} is not a neuron of a "
            f"{interp.mul_size}-neuron multiplier block"
        )
    neurons = interp.num_original + k * interp.mul_size
    if interp.net.num_neurons != neurons:
        raise MbnInputError(
            f"interpreter.net: {interp.num_original} original neurons + {k} multipliers of "
            f"{interp.mul_size} make {neurons} neurons, but W is "
            f"{interp.net.num_neurons}x{interp.net.num_neurons}"
        )
    if interp.net.num_inputs != interp.num_data_inputs + k:
        raise MbnInputError(
            f"interpreter.net: {interp.num_data_inputs} data inputs + {k} program inputs make "
            f"{interp.num_data_inputs + k} inputs, but WE has {interp.net.num_inputs} columns"
        )
    for conn in interp.connections:
        if not isinstance(conn, Connection):
            raise MbnInputError(f"interpreter.connections: {conn!r} is not a Connection")
        limit = interp.num_original if conn.kind == "W" else interp.num_data_inputs
        if conn.i >= interp.num_original or conn.j >= limit:
            raise MbnInputError(
                f"interpreter.connections: {conn} is out of range for {interp.num_original} "
                f"original neurons and {interp.num_data_inputs} inputs"
            )
    lower = np.asarray(interp.lower, np.float64)
    upper = np.asarray(interp.upper, np.float64)
    for name, arr in (("lower", lower), ("upper", upper)):
        if arr.shape != (k,):
            raise MbnInputError(
                f"interpreter.{name}: expected {k} values (one per connection), got shape "
                f"{arr.shape}"
            )
        if not np.all(np.isfinite(arr)):
            raise MbnInputError(f"interpreter.{name}: values must be finite")
    if np.any(lower >= upper):
        c = int(np.argmax(lower >= upper))
        raise MbnInputError(
            f"interpreter: bounds of {interp.connections[c]}: lower {lower[c]:g} must be < "
            f"upper {upper[c]:g}"
        )


def _refuse_text(values: Any, where: str) -> None:
    """Refuse program values written as text (``"0.5"``, which NumPy would read as 0.5) or as
    true/false: a program is numbers."""
    if isinstance(values, (str, bytes)):
        raise MbnInputError(f"{where}: expected a list of numbers, got text")
    if isinstance(values, np.ndarray):
        if values.dtype.kind in "USb":
            raise MbnInputError(f"{where}: expected numbers, got an array of {values.dtype}")
        if values.dtype.kind != "O":
            return
        values = values.tolist()
    if not isinstance(values, (list, tuple)):
        return  # a JAX array, ...: numbers
    for i, v in enumerate(values):
        if isinstance(v, (str, bytes)):
            raise MbnInputError(f"{where}: expected numbers, got text {repr(v)[:24]} at index {i}")
        if isinstance(v, (bool, np.bool_)):
            raise MbnInputError(f"{where}: expected numbers, got {str(v).lower()} at index {i}")


def _normalise_programs(
    programs: Mapping[str, Sequence[float]], k: int
) -> dict[str, tuple[float, ...]]:
    if not isinstance(programs, Mapping):
        raise MbnInputError(f"programs must be an object of name -> list, got {programs!r}")
    out: dict[str, tuple[float, ...]] = {}
    for name, values in programs.items():
        if not isinstance(name, str) or not name:
            raise MbnInputError(f"programs: a program name must be a non-empty string: {name!r}")
        _refuse_text(values, f"programs.{name}")
        try:
            arr = np.asarray(values, dtype=np.float64)
        except (TypeError, ValueError):
            raise MbnInputError(f"programs.{name}: not a list of numbers") from None
        if arr.shape != (k,):
            raise MbnInputError(
                f"programs.{name}: expected {k} values (one per programmable connection), got "
                f"shape {arr.shape}"
            )
        bad = ~np.isfinite(arr) | (arr < 0) | (arr > 1)
        if np.any(bad):
            c = int(np.argmax(bad))
            raise MbnInputError(
                f"programs.{name}: values must be in [0, 1], got {arr[c]:g} at index {c}"
            )
        out[name] = tuple(float(v) for v in arr)
    return out


#: How an interpreter may be simulated (:attr:`InterpreterControllerSpec.simulation`).
SIMULATIONS = ("dense", "blocks")


@dataclass(frozen=True, eq=False)
class InterpreterControllerSpec:
    """The fixed-weight interpreter with named programs.

    Attributes:
        interpreter: the interpreter
            (:func:`mbn.networks.programmable.build_interpreter`), 3 data inputs.
        programs: name -> program (one value in [0, 1] per programmable connection), e.g.
            ``{"right": [...], "left": [...]}``.
        sensors, motor, dt, method, metadata: as in :class:`CTRNNControllerSpec`; the motor
            neurons are original neurons (the interpreter puts them first).
        substeps: interpreter steps per robot step, keeping h / tau_m = 0.1 (multipliers at
            tau/10: 20 steps of 5 ms for tau = 0.5 s; at tau/40, as ``mbn reproduce`` builds
            them: 80).
        simulation: how the interpreter is simulated: ``"dense"``, as one CTRNN of all its
            neurons, or ``"blocks"``, by its structure (the original neurons beside a batch of
            multipliers, :mod:`mbn.networks.structured`): the same network, a cost linear in the
            number of programmable connections.
        kind: the file kind (class constant).
    """

    kind: ClassVar[str] = KIND_INTERPRETER
    interpreter: Interpreter
    programs: Mapping[str, Sequence[float]]
    sensors: SensorConfig = field(default_factory=SensorConfig)
    motor: MotorMap = field(default_factory=MotorMap)
    dt: float = 0.1
    substeps: int = NETWORK_SUBSTEPS
    method: str = "euler"
    metadata: Mapping[str, Any] = field(default_factory=dict)
    simulation: str = "dense"

    def __post_init__(self) -> None:
        if self.simulation not in SIMULATIONS:
            raise MbnInputError(
                f"simulation must be one of {', '.join(SIMULATIONS)}, got {self.simulation!r}"
            )
        _check_interpreter(self.interpreter)
        k = len(self.interpreter.connections)
        object.__setattr__(self, "programs", _normalise_programs(self.programs, k))
        _check_sensors(self.sensors)
        _check_motor(
            self.motor, self.interpreter.num_original, "the interpreter's original network"
        )
        _check_run_settings(self.dt, self.substeps, self.method)
        _check_metadata(self.metadata)
        object.__setattr__(self, "metadata", dict(self.metadata))


@dataclass(frozen=True)
class PMInitial:
    """Where the program module starts, and the rule the MBN follows from there until its first
    tile.

    Attributes:
        rule: the rule the state stands for (the state the PM latches after a one-colour tile
            stands for "right"); one of the MBN's ``tile_rules``.
        potentials: the PM's initial membrane potentials, one per PM neuron.
    """

    rule: str
    potentials: tuple[float, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "rule", parse_rule(self.rule).name)
        try:
            arr = np.asarray(self.potentials, dtype=np.float64)
        except (TypeError, ValueError):
            raise MbnInputError("potentials: not a list of numbers") from None
        if arr.ndim != 1 or not np.all(np.isfinite(arr)):
            raise MbnInputError("potentials: expected a list of finite numbers")
        object.__setattr__(self, "potentials", tuple(float(v) for v in arr))


@dataclass(frozen=True, eq=False)
class MBNControllerSpec:
    """The Multiple Behavior Network: a program module (PM) that sets the interpreter's program.

    Attributes:
        interpreter_spec: the interpreter (IM), with its sensors, motor, dt and sub-steps; its
            ``programs`` are kept for reference (and to run the IM alone with one of them).
        program_module: a CTRNN with one input per tile kind, ``[camera == 1, camera == 2,
            ...]`` (2 in the paper).
        program_neurons: PM neurons whose firing rates are the program, one per programmable
            connection, in program order; or, with a ``readout``, the PM's code.
        readout: None (the paper's: the rates are the program), or a fixed ``(K, P)`` matrix
            whose columns are programs: the program is ``clip(readout @ code, 0, 1)`` for the
            code of the ``P`` program neurons (a PM that latches the code ``e_k`` sends column
            k) — a program memory read by the PM's output layer; the interpreter is unchanged.
        tile_rules: the rule a tile of 1, 2, ... colours puts in force (the paper's: right,
            left); the PM has one camera input per tile kind.
        pm_substeps: Euler steps of the PM per robot step.
        camera: the blob-finding camera the PM reads (field of view and range).
        initial: where the PM starts and the rule that stands for (:class:`PMInitial`); None:
            at rest (potentials 0), with no rule before the first tile (files written before
            the field).
        metadata: free JSON-serialisable information: the file's ``metadata`` (that of
            ``interpreter_spec`` is not written).
        kind: the file kind (class constant).
    """

    kind: ClassVar[str] = KIND_MBN
    interpreter_spec: InterpreterControllerSpec
    program_module: CTRNN
    program_neurons: tuple[int, ...]
    pm_substeps: int = 4
    camera: CameraConfig = field(default_factory=CameraConfig)
    initial: PMInitial | None = None
    metadata: Mapping[str, Any] = field(default_factory=dict)
    readout: Sequence[Sequence[float]] | None = None
    tile_rules: tuple[str, ...] = ("right", "left")

    def __post_init__(self) -> None:
        rules = _tile_rules(self.tile_rules, "program_module.tile_rules")
        object.__setattr__(self, "tile_rules", rules)
        if not isinstance(self.camera, CameraConfig):
            raise MbnInputError(f"camera must be a CameraConfig, got {type(self.camera).__name__}")
        if not isinstance(self.interpreter_spec, InterpreterControllerSpec):
            raise MbnInputError(
                "interpreter_spec must be an InterpreterControllerSpec, got "
                f"{type(self.interpreter_spec).__name__}"
            )
        _check_single(self.program_module, "program_module.network")
        pm = self.program_module
        if pm.num_inputs != len(rules):
            raise MbnInputError(
                f"program_module.network: the program module reads {len(rules)} camera inputs "
                f"(one per tile kind of tile_rules), but WE has {pm.num_inputs} columns"
            )
        neurons = tuple(self.program_neurons)
        if not all(isinstance(i, int) and not isinstance(i, bool) for i in neurons):
            raise MbnInputError(
                f"program_module.program_neurons must be integers, got {list(neurons)}"
            )
        k = len(self.interpreter_spec.interpreter.connections)
        if self.readout is not None:
            rows = self.readout if isinstance(self.readout, (list, tuple)) else [self.readout]
            for row in rows:
                _refuse_text(row, "program_module.readout")
            try:
                R = np.asarray(self.readout, dtype=np.float64)
            except (TypeError, ValueError):
                raise MbnInputError("program_module.readout: not a matrix of numbers") from None
            if R.shape != (k, len(neurons)) or not np.all(np.isfinite(R)):
                raise MbnInputError(
                    f"program_module.readout: expected a finite {k} x {len(neurons)} matrix "
                    f"(programmable connections x program neurons), got shape {R.shape}"
                )
            if np.any((R < 0) | (R > 1)):
                raise MbnInputError("program_module.readout: its columns are programs, in [0, 1]")
            object.__setattr__(self, "readout", tuple(tuple(float(v) for v in r) for r in R))
        elif len(neurons) != k:
            raise MbnInputError(
                f"program_module.program_neurons: the interpreter has {k} programmable "
                f"connections, got {len(neurons)} program neurons"
            )
        if any(not 0 <= i < pm.num_neurons for i in neurons):
            raise MbnInputError(
                f"program_module.program_neurons {list(neurons)}: indices must be in "
                f"0..{pm.num_neurons - 1}"
            )
        if len(set(neurons)) != len(neurons):
            raise MbnInputError(
                f"program_module.program_neurons {list(neurons)}: a neuron is listed twice"
            )
        object.__setattr__(self, "program_neurons", neurons)
        if (
            isinstance(self.pm_substeps, bool)
            or not isinstance(self.pm_substeps, int)
            or self.pm_substeps < 1
        ):
            raise MbnInputError(
                f"program_module.substeps must be an integer >= 1, got {self.pm_substeps!r}"
            )
        if self.initial is not None:
            if not isinstance(self.initial, PMInitial):
                raise MbnInputError(
                    f"initial must be a PMInitial or None, got {type(self.initial).__name__}"
                )
            if self.initial.rule not in rules:
                raise MbnInputError(
                    f"program_module.initial.rule: {self.initial.rule} is none of the tile "
                    f"rules ({', '.join(rules)})"
                )
            if len(self.initial.potentials) != self.program_module.num_neurons:
                raise MbnInputError(
                    f"program_module.initial.potentials: the program module has "
                    f"{self.program_module.num_neurons} neurons, got "
                    f"{len(self.initial.potentials)} potentials"
                )
        _check_metadata(self.metadata)
        object.__setattr__(self, "metadata", dict(self.metadata))


@dataclass(frozen=True, eq=False)
class SwitchedControllerSpec:
    """Plain CTRNN followers, one per rule, switched by the tiles the camera sees: the MBN's
    baselines (``docs/controllers.md``, :mod:`mbn.control.switched`).

    Attributes:
        networks: rule -> the follower of that rule (a plain CTRNN reading I1..I3; e.g. the
            network each program of an MBN encodes, :func:`decoded_networks`); every tile rule
            has one, and each one is a tile rule's. All have the same neurons (one state is
            swapped between them) and dtype. Rule names are kept as :func:`parse_rule` names
            them, in the order given.
        mode: ``"swap"`` (the oracle: one state of potentials, the weights swapped to the network
            of the rule in force; the potentials are kept across a swap) or ``"gate"`` (every
            network runs on the same inputs with its own potentials, the one of the rule in force
            drives).
        tile_rules: the rule a tile of 1, 2, ... colours puts in force (the paper's: right,
            left), read from the camera as the MBN's program module reads it.
        initial: the rule in force before the first tile (one of ``tile_rules``), or None: no
            rule is declared (the network of a one-colour tile drives until the first tile).
        camera: the blob-finding camera it reads.
        sensors, motor, dt, substeps, method, metadata: as in :class:`CTRNNControllerSpec`
            (the motor neurons are every network's).
        kind: the file kind (class constant).
    """

    kind: ClassVar[str] = KIND_SWITCHED
    networks: Mapping[str, CTRNN]
    mode: str = "swap"
    tile_rules: tuple[str, ...] = ("right", "left")
    initial: str | None = None
    camera: CameraConfig = field(default_factory=CameraConfig)
    sensors: SensorConfig = field(default_factory=SensorConfig)
    motor: MotorMap = field(default_factory=MotorMap)
    dt: float = 0.1
    substeps: int = NETWORK_SUBSTEPS
    method: str = "euler"
    metadata: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.mode, str) or self.mode not in MODES:
            raise MbnInputError(f"mode must be one of {', '.join(MODES)}, got {self.mode!r}")
        rules = _tile_rules(self.tile_rules, "tile_rules")
        object.__setattr__(self, "tile_rules", rules)
        if not isinstance(self.camera, CameraConfig):
            raise MbnInputError(f"camera must be a CameraConfig, got {type(self.camera).__name__}")
        nets = _rule_networks(self.networks)
        object.__setattr__(self, "networks", nets)
        missing = [r for r in dict.fromkeys(rules) if r not in nets]
        if missing:
            raise MbnInputError(
                f"tile_rules: no network for rule {missing[0]} (networks: {', '.join(nets)})"
            )
        unused = [r for r in nets if r not in rules]
        if unused:
            raise MbnInputError(
                f"networks.{unused[0]}: no tile puts {unused[0]} in force (tile_rules: "
                f"{', '.join(rules)})"
            )
        if self.initial is not None:
            try:
                initial = parse_rule(self.initial).name
            except MbnInputError as exc:
                raise MbnInputError(f"initial: {exc}") from None
            if initial not in rules:
                raise MbnInputError(
                    f"initial: {initial} is none of the tile rules ({', '.join(rules)})"
                )
            object.__setattr__(self, "initial", initial)
        _check_sensors(self.sensors)
        _check_motor(self.motor, self.num_neurons, "the networks")
        _check_run_settings(self.dt, self.substeps, self.method)
        _check_metadata(self.metadata)
        object.__setattr__(self, "metadata", dict(self.metadata))

    @property
    def rules(self) -> tuple[str, ...]:
        """The rules of :attr:`networks`, in order: a state's ``rule`` indexes them."""
        return tuple(self.networks)

    @property
    def tile_networks(self) -> tuple[int, ...]:
        """The index in :attr:`rules` of the network a tile of 1, 2, ... colours puts in force."""
        return tuple(self.rules.index(r) for r in self.tile_rules)

    @property
    def num_neurons(self) -> int:
        """The neurons of each network."""
        return next(iter(self.networks.values())).num_neurons


def _rule_networks(networks: Mapping[str, CTRNN]) -> dict[str, CTRNN]:
    """``networks`` by rule name (:func:`parse_rule`), checked: plain CTRNNs reading I1..I3, all
    of the same neurons and dtype."""
    if not isinstance(networks, Mapping) or not networks:
        raise MbnInputError("networks: expected an object of rule -> network, with one at least")
    out: dict[str, CTRNN] = {}
    given: dict[str, str] = {}
    for key, net in networks.items():
        try:
            name = parse_rule(key).name
        except MbnInputError as exc:
            raise MbnInputError(f"networks: {exc}") from None
        if name in out:
            raise MbnInputError(
                f"networks: {given[name]!r} and {key!r} are the same rule ({name}), given twice"
            )
        what = f"networks.{name}"
        _check_single(net, what)
        if net.num_inputs != NUM_INPUTS:
            raise MbnInputError(
                f"{what}: a controller reads the paper's {NUM_INPUTS} inputs I1..I3, but WE has "
                f"{net.num_inputs} columns"
            )
        if out:
            first, ref = next(iter(out.items()))
            if net.num_neurons != ref.num_neurons:
                raise MbnInputError(
                    f"{what}: {net.num_neurons} neurons, but networks.{first} has "
                    f"{ref.num_neurons}: the networks must all have the same shape (one state is "
                    "switched between them)"
                )
            if net.dtype != ref.dtype:
                raise MbnInputError(
                    f"{what}: dtype {net.dtype}, but networks.{first} is {ref.dtype}: the "
                    "networks must all have the same dtype"
                )
        out[name] = net
        given[name] = key
    return out


def decoded_networks(spec: InterpreterControllerSpec | MBNControllerSpec) -> dict[str, CTRNN]:
    """The network each named program of an interpreter (or of an MBN's interpreter) encodes:
    the interpreter's original neurons, each programmable connection at its decoded weight
    ``lower + p (upper - lower)`` (eq. 2) — the follower the interpreter emulates with that
    program, without its multipliers."""
    im_spec = spec.interpreter_spec if isinstance(spec, MBNControllerSpec) else spec
    if not isinstance(im_spec, InterpreterControllerSpec):
        raise MbnInputError(
            f"decoded_networks: expected an interpreter or MBN spec, got {type(spec).__name__}"
        )
    interp = im_spec.interpreter
    n, m = interp.num_original, interp.num_data_inputs
    net = interp.net
    W = np.asarray(net.W, np.float64)[:n, :n]
    WE = np.asarray(net.WE, np.float64)[:n, :m]
    out: dict[str, CTRNN] = {}
    for name, program in im_spec.programs.items():
        weights = np.asarray(interp.decode(jnp.asarray(program, net.dtype)), np.float64)
        Wp, WEp = W.copy(), WE.copy()
        for conn, value in zip(interp.connections, weights, strict=True):
            (Wp if conn.kind == "W" else WEp)[conn.i, conn.j] = value
        out[name] = make_ctrnn(
            Wp,
            WEp,
            np.asarray(net.tau, np.float64)[:n],
            bias=np.asarray(net.bias, np.float64)[:n],
            gain=np.asarray(net.gain, np.float64)[:n],
            dtype=net.dtype,
            name=f"programs.{name}",
        )
    return out


def switched_from_mbn(
    spec: MBNControllerSpec,
    mode: str = "swap",
    *,
    substeps: int | None = None,
    metadata: Mapping[str, Any] | None = None,
) -> SwitchedControllerSpec:
    """The baseline ``mode`` of an MBN: for each of its tile rules the network its stored program
    of that rule encodes (:func:`decoded_networks`; the programs are named by rule, as ``"right"``
    and ``"left"``), switched by the same camera and tile rules, from its ``initial`` rule, with
    its interpreter's sensors, motor, ``dt``, ``method`` and ``substeps`` (or ``substeps``)."""
    if not isinstance(spec, MBNControllerSpec):
        raise MbnInputError(f"switched_from_mbn: expected an MBN spec, got {type(spec).__name__}")
    by_rule: dict[str, CTRNN] = {}
    for name, net in decoded_networks(spec).items():
        try:
            by_rule.setdefault(parse_rule(name).name, net)
        except MbnInputError:
            continue  # a program not named by a rule
    missing = [r for r in dict.fromkeys(spec.tile_rules) if r not in by_rule]
    if missing:
        raise MbnInputError(
            f"programs: the MBN has no program named {missing[0]} for its tile rule "
            f"(programs: {', '.join(spec.interpreter_spec.programs) or 'none'})"
        )
    im = spec.interpreter_spec
    return SwitchedControllerSpec(
        networks={r: by_rule[r] for r in dict.fromkeys(spec.tile_rules)},
        mode=mode,
        tile_rules=spec.tile_rules,
        initial=spec.initial.rule if spec.initial is not None else None,
        camera=spec.camera,
        sensors=im.sensors,
        motor=im.motor,
        dt=im.dt,
        substeps=im.substeps if substeps is None else substeps,
        method=im.method,
        metadata=dict(metadata or {}),
    )


ControllerSpec = (
    CTRNNControllerSpec | InterpreterControllerSpec | MBNControllerSpec | SwitchedControllerSpec
)
