"""Controller files: plain CTRNN controllers, the interpreter with its programs, and the MBN.

A controller file is one JSON object that says what it is (``kind``, ``format_version``,
``mbn_version``) and holds everything needed to drive the robot: the network(s), which sonars are
read and how, the motor mapping, the robot step ``dt`` and the integration sub-steps. Three kinds:

* ``"mbn.controller.ctrnn"``: a CTRNN fed the paper's inputs I1..I3 (``network``, as
  :meth:`mbn.networks.ctrnn.CTRNN.to_dict` writes it, with ``tau`` inside); optional ``behavior``.
* ``"mbn.controller.interpreter"``: the fixed-weight interpreter of :mod:`mbn.networks.programmable`
  (``interpreter``: its network, programmable ``connections`` such as ``"W[1,2]"``, ``lower``,
  ``upper`` and its block layout) and named ``programs`` (``{"right": [...], "left": [...]}``).
* ``"mbn.controller.mbn"``: the Multiple Behavior Network: an interpreter section as above plus a
  ``program_module``: a CTRNN whose two inputs encode the camera (a one-colour tile in view, a
  two-colour tile in view) and whose ``program_neurons``' firing rates are the program.

Every file also has ``sensors`` (:class:`~mbn.world.sensors.SensorConfig` fields), ``motor``
(:class:`~mbn.control.ctrnn.MotorMap` fields), ``dt``, ``substeps``, ``method`` and a free
``metadata`` object. :func:`save_controller` writes a spec atomically (after checking that what it
writes loads back); :func:`load_controller` reads and validates a file (every error one line that
names the file) and returns a :class:`LoadedController` ready for
:func:`mbn.experiments.trials.run_trials`. The format is described in ``docs/controllers.md``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from mbn.control.ctrnn import (
    NETWORK_SUBSTEPS,
    CTRNNState,
    MotorMap,
    ProgrammedState,
    ctrnn_controller,
    interpreter_controller,
)
from mbn.errors import MbnInputError
from mbn.networks.ctrnn import CTRNN, euler_step, firing_rate
from mbn.networks.programmable import Connection, Interpreter
from mbn.world.engine import CameraConfig
from mbn.world.sensors import PAPER_SONARS, SensorConfig

__all__ = [
    "FORMAT_VERSION",
    "KINDS",
    "KIND_CTRNN",
    "KIND_INTERPRETER",
    "KIND_MBN",
    "CTRNNControllerSpec",
    "ControllerSpec",
    "InterpreterControllerSpec",
    "LoadedController",
    "MBNControllerSpec",
    "MBNControllerState",
    "controller_from_dict",
    "controller_to_dict",
    "load_controller",
    "make_controller",
    "make_mbn_controller",
    "read_controller_spec",
    "save_controller",
]

KIND_CTRNN = "mbn.controller.ctrnn"
KIND_INTERPRETER = "mbn.controller.interpreter"
KIND_MBN = "mbn.controller.mbn"
#: The controller kinds, in the order error messages list them.
KINDS: tuple[str, ...] = (KIND_CTRNN, KIND_INTERPRETER, KIND_MBN)
FORMAT_VERSION = 1
#: Kind of a multiplier file (:mod:`mbn.networks.multiplier`), recognised to give a clear error.
_MULTIPLIER_KIND = "mbn.multiplier"
#: Number of data inputs every controller reads: the paper's I1..I3 (eq. 3).
NUM_INPUTS = 3
#: Inputs of the program module: a one-colour tile in view, a two-colour tile in view.
PM_INPUTS = 2

Controller = Callable[[Any, Any], tuple[Any, tuple[Array, Array]]]


# --------------------------------------------------------------------------------------------
# Specs: what a file holds, as Python objects (validated on construction)
# --------------------------------------------------------------------------------------------


def _check_run_settings(dt: float, substeps: int, method: str) -> None:
    if isinstance(dt, bool) or not isinstance(dt, (int, float)) or not (0 < dt < math.inf):
        raise MbnInputError(f"dt must be a finite number > 0, got {dt!r}")
    if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
        raise MbnInputError(f"substeps must be an integer >= 1, got {substeps!r}")
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
        net: the network (unbatched, 3 inputs).
        sensors: the sonars cast and their normalisation (must include the paper's 10).
        motor: which neurons set ``v`` and ``w``.
        dt: robot step (s).
        substeps: network steps per robot step.
        method: "euler" or "rk4".
        behavior: what it was made for, "right" or "left" (or None).
        metadata: free JSON-serialisable information (how it was made, scores, ...).
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

    def __post_init__(self) -> None:
        _check_single(self.net, "network")
        if self.net.num_inputs != NUM_INPUTS:
            raise MbnInputError(
                f"network: a controller reads the paper's {NUM_INPUTS} inputs I1..I3, but WE has "
                f"{self.net.num_inputs} columns"
            )
        _check_sensors(self.sensors)
        _check_motor(self.motor, self.net.num_neurons, "the network")
        _check_run_settings(self.dt, self.substeps, self.method)
        if self.behavior not in (None, "right", "left"):
            raise MbnInputError(f"behavior must be right, left or null, got {self.behavior!r}")
        _check_metadata(self.metadata)
        object.__setattr__(self, "metadata", dict(self.metadata))


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


def _normalise_programs(
    programs: Mapping[str, Sequence[float]], k: int
) -> dict[str, tuple[float, ...]]:
    if not isinstance(programs, Mapping):
        raise MbnInputError(f"programs must be an object of name -> list, got {programs!r}")
    out: dict[str, tuple[float, ...]] = {}
    for name, values in programs.items():
        if not isinstance(name, str) or not name:
            raise MbnInputError(f"programs: a program name must be a non-empty string: {name!r}")
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
        substeps: interpreter steps per robot step (the multipliers run at tau/10: 20 steps of
            5 ms for tau = 0.5 s).
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

    def __post_init__(self) -> None:
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


@dataclass(frozen=True, eq=False)
class MBNControllerSpec:
    """The Multiple Behavior Network: a program module (PM) that sets the interpreter's program.

    Attributes:
        interpreter_spec: the interpreter (IM), with its sensors, motor, dt and sub-steps; its
            ``programs`` are kept for reference (and to run the IM alone with one of them).
        program_module: a CTRNN with 2 inputs ``[camera == 1, camera == 2]``.
        program_neurons: PM neurons whose firing rates are the program, one per programmable
            connection, in program order.
        pm_substeps: Euler steps of the PM per robot step.
        camera: the blob-finding camera the PM reads (field of view and range).
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
    metadata: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.camera, CameraConfig):
            raise MbnInputError(f"camera must be a CameraConfig, got {type(self.camera).__name__}")
        if not isinstance(self.interpreter_spec, InterpreterControllerSpec):
            raise MbnInputError(
                "interpreter_spec must be an InterpreterControllerSpec, got "
                f"{type(self.interpreter_spec).__name__}"
            )
        _check_single(self.program_module, "program_module.network")
        pm = self.program_module
        if pm.num_inputs != PM_INPUTS:
            raise MbnInputError(
                f"program_module.network: the program module reads {PM_INPUTS} camera inputs "
                f"(one-colour, two-colour tile in view), but WE has {pm.num_inputs} columns"
            )
        neurons = tuple(self.program_neurons)
        if not all(isinstance(i, int) and not isinstance(i, bool) for i in neurons):
            raise MbnInputError(
                f"program_module.program_neurons must be integers, got {list(neurons)}"
            )
        k = len(self.interpreter_spec.interpreter.connections)
        if len(neurons) != k:
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
        _check_metadata(self.metadata)
        object.__setattr__(self, "metadata", dict(self.metadata))


ControllerSpec = CTRNNControllerSpec | InterpreterControllerSpec | MBNControllerSpec


# --------------------------------------------------------------------------------------------
# Spec <-> JSON
# --------------------------------------------------------------------------------------------


def _sensors_to_dict(sensors: SensorConfig) -> dict[str, Any]:
    return {
        "sonars": list(sensors.sonars),
        "normalization": sensors.normalization,
        "near": sensors.near,
        "far": sensors.far,
    }


def _motor_to_dict(motor: MotorMap) -> dict[str, Any]:
    return {
        "speed_neuron": motor.speed_neuron,
        "turn_neuron": motor.turn_neuron,
        "v_max": motor.v_max,
        "w_max": motor.w_max,
    }


def _interpreter_to_dict(interp: Interpreter) -> dict[str, Any]:
    return {
        "net": interp.net.to_dict(),
        "connections": [str(c) for c in interp.connections],
        "lower": np.asarray(interp.lower, np.float64).tolist(),
        "upper": np.asarray(interp.upper, np.float64).tolist(),
        "num_original": interp.num_original,
        "num_data_inputs": interp.num_data_inputs,
        "mul_size": interp.mul_size,
        "mul_output": interp.mul_output,
    }


def _header(kind: str) -> dict[str, Any]:
    from mbn import __version__

    return {"kind": kind, "format_version": FORMAT_VERSION, "mbn_version": __version__}


def _interpreter_body(spec: InterpreterControllerSpec) -> dict[str, Any]:
    return {
        "interpreter": _interpreter_to_dict(spec.interpreter),
        "programs": {name: list(p) for name, p in spec.programs.items()},
        "sensors": _sensors_to_dict(spec.sensors),
        "motor": _motor_to_dict(spec.motor),
        "dt": spec.dt,
        "substeps": spec.substeps,
        "method": spec.method,
    }


def controller_to_dict(spec: ControllerSpec) -> dict[str, Any]:
    """The self-describing JSON form of a controller spec (see ``docs/controllers.md``)."""
    if isinstance(spec, CTRNNControllerSpec):
        return {
            **_header(KIND_CTRNN),
            "behavior": spec.behavior,
            "network": spec.net.to_dict(),
            "sensors": _sensors_to_dict(spec.sensors),
            "motor": _motor_to_dict(spec.motor),
            "dt": spec.dt,
            "substeps": spec.substeps,
            "method": spec.method,
            "metadata": dict(spec.metadata),
        }
    if isinstance(spec, InterpreterControllerSpec):
        return {
            **_header(KIND_INTERPRETER),
            **_interpreter_body(spec),
            "metadata": dict(spec.metadata),
        }
    if isinstance(spec, MBNControllerSpec):
        return {
            **_header(KIND_MBN),
            **_interpreter_body(spec.interpreter_spec),
            "program_module": {
                "network": spec.program_module.to_dict(),
                "program_neurons": list(spec.program_neurons),
                "substeps": spec.pm_substeps,
                "camera": {"fov_deg": spec.camera.fov_deg, "range": spec.camera.range},
            },
            "metadata": dict(spec.metadata),
        }
    raise MbnInputError(
        f"not a controller spec: {type(spec).__name__} (expected CTRNNControllerSpec, "
        "InterpreterControllerSpec or MBNControllerSpec)"
    )


def _object(value: Any, where: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise MbnInputError(f"{where}: expected an object, got {type(value).__name__}")
    return value


def _fields(
    data: dict[str, Any], where: str, required: Sequence[str], optional: Sequence[str] = ()
) -> None:
    """Refuse missing required keys and unknown keys of an object."""
    missing = [k for k in required if k not in data]
    if missing:
        plural = "s" if len(missing) > 1 else ""
        raise MbnInputError(f"{where}: missing field{plural} {', '.join(map(repr, missing))}")
    unknown = sorted(set(data) - set(required) - set(optional))
    if unknown:
        raise MbnInputError(
            f"{where}: unknown field(s) {', '.join(map(repr, unknown))} (expected "
            f"{', '.join(list(required) + list(optional))})"
        )


def _integer(value: Any, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise MbnInputError(f"{where}: expected an integer, got {value!r}")
    return value


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise MbnInputError(f"{where}: expected a finite number, got {value!r}")
    return float(value)


def _sensors_from_dict(value: Any, where: str) -> SensorConfig:
    data = _object(value, f"{where}: sensors")
    _fields(data, f"{where}: sensors", ["sonars"], ["normalization", "near", "far"])
    sonars = data["sonars"]
    if not isinstance(sonars, list) or not all(
        isinstance(s, int) and not isinstance(s, bool) for s in sonars
    ):
        raise MbnInputError(f"{where}: sensors.sonars: expected a list of integers, got {sonars!r}")
    defaults = SensorConfig()
    try:
        return SensorConfig(
            sonars=tuple(sonars),
            normalization=data.get("normalization", defaults.normalization),
            near=_number(data.get("near", defaults.near), f"{where}: sensors.near"),
            far=_number(data.get("far", defaults.far), f"{where}: sensors.far"),
        )
    except MbnInputError as exc:
        if str(exc).startswith(where):
            raise
        raise MbnInputError(f"{where}: sensors: {exc}") from None


def _motor_from_dict(value: Any, where: str) -> MotorMap:
    data = _object(value, f"{where}: motor")
    _fields(data, f"{where}: motor", ["speed_neuron", "turn_neuron"], ["v_max", "w_max"])
    defaults = MotorMap()
    speed = _integer(data["speed_neuron"], f"{where}: motor.speed_neuron")
    turn = _integer(data["turn_neuron"], f"{where}: motor.turn_neuron")
    v_max = _number(data.get("v_max", defaults.v_max), f"{where}: motor.v_max")
    w_max = _number(data.get("w_max", defaults.w_max), f"{where}: motor.w_max")
    try:
        return MotorMap(speed_neuron=speed, turn_neuron=turn, v_max=v_max, w_max=w_max)
    except MbnInputError as exc:
        raise MbnInputError(f"{where}: motor: {exc}") from None


def _network_from_dict(value: Any, where: str) -> CTRNN:
    data = _object(value, where)
    _fields(data, where, ["W", "WE", "tau"], ["bias", "gain"])
    net = CTRNN.from_dict(data, where=where)
    if net.W.ndim != 2:
        raise MbnInputError(f"{where}: expected one network, got W of shape {tuple(net.W.shape)}")
    return net


def _interpreter_from_dict(value: Any, where: str) -> Interpreter:
    here = f"{where}: interpreter"
    data = _object(value, here)
    keys = ["net", "connections", "lower", "upper", "num_original", "num_data_inputs"]
    _fields(data, here, [*keys, "mul_size", "mul_output"])
    net = _network_from_dict(data["net"], f"{here}.net")
    conns = data["connections"]
    if not isinstance(conns, list) or not all(isinstance(c, str) for c in conns):
        raise MbnInputError(
            f"{here}.connections: expected a list of strings like 'W[1,2]', got {conns!r}"
        )
    try:
        connections = tuple(Connection.parse(c) for c in conns)
    except MbnInputError as exc:
        raise MbnInputError(f"{here}.connections: {exc}") from None
    bounds = {}
    for name in ("lower", "upper"):
        values = data[name]
        if not isinstance(values, list):
            raise MbnInputError(f"{here}.{name}: expected a list of numbers, got {values!r}")
        bounds[name] = [_number(v, f"{here}.{name}") for v in values]
    ints = {
        name: _integer(data[name], f"{here}.{name}")
        for name in ("num_original", "num_data_inputs", "mul_size", "mul_output")
    }
    return Interpreter(
        net=net,
        lower=jnp.asarray(bounds["lower"], net.dtype),
        upper=jnp.asarray(bounds["upper"], net.dtype),
        connections=connections,
        **ints,
    )


def _run_settings(data: dict[str, Any], where: str) -> dict[str, Any]:
    return {
        "dt": _number(data["dt"], f"{where}: dt"),
        "substeps": _integer(data["substeps"], f"{where}: substeps"),
        "method": data["method"],
    }


def _check_header(data: Any, where: str) -> str:
    if not isinstance(data, dict):
        raise MbnInputError(
            f"{where}: not a controller file (a JSON {type(data).__name__}, expected an object "
            f"with a 'kind', one of {', '.join(KINDS)})"
        )
    kind = data.get("kind")
    if kind == _MULTIPLIER_KIND:
        raise MbnInputError(
            f"{where}: is a multiplier, not a controller (kind {kind!r}; expected one of "
            f"{', '.join(KINDS)})"
        )
    if kind not in KINDS:
        raise MbnInputError(
            f"{where}: not a controller file (kind {kind!r}, expected one of {', '.join(KINDS)})"
        )
    if "format_version" not in data:
        raise MbnInputError(f"{where}: missing field 'format_version'")
    version = data["format_version"]
    if version != FORMAT_VERSION or isinstance(version, bool):
        raise MbnInputError(
            f"{where}: format_version {version!r} is not supported (this mbn reads "
            f"{FORMAT_VERSION})"
        )
    return str(kind)


def controller_from_dict(data: Any, *, where: str = "controller") -> ControllerSpec:
    """Parse and validate the JSON form of a controller (:func:`controller_to_dict`).

    Raises:
        MbnInputError: one line naming ``where`` and what is wrong.
    """
    kind = _check_header(data, where)
    header = ["kind", "format_version"]
    optional = ["mbn_version", "metadata"]
    common = ["sensors", "motor", "dt", "substeps", "method"]
    if kind == KIND_CTRNN:
        _fields(data, where, [*header, "network", *common], [*optional, "behavior"])
        net = _network_from_dict(data["network"], f"{where}: network")
        sensors = _sensors_from_dict(data["sensors"], where)
        motor = _motor_from_dict(data["motor"], where)
        settings = _run_settings(data, where)
        metadata = data.get("metadata", {})
        behavior = data.get("behavior")
        return _build(
            where,
            lambda: CTRNNControllerSpec(
                net=net,
                sensors=sensors,
                motor=motor,
                behavior=behavior,
                metadata=metadata,
                **settings,
            ),
        )
    body = ["interpreter", "programs", *common]
    if kind == KIND_INTERPRETER:
        _fields(data, where, [*header, *body], optional)
    else:
        _fields(data, where, [*header, *body, "program_module"], optional)
    interp = _interpreter_from_dict(data["interpreter"], where)
    programs = _object(data["programs"], f"{where}: programs")
    if kind == KIND_INTERPRETER and not programs:
        raise MbnInputError(f"{where}: programs: an interpreter file needs at least one program")
    sensors = _sensors_from_dict(data["sensors"], where)
    motor = _motor_from_dict(data["motor"], where)
    settings = _run_settings(data, where)
    metadata = data.get("metadata", {})
    im_spec = _build(
        where,
        lambda: InterpreterControllerSpec(
            interpreter=interp,
            programs=programs,
            sensors=sensors,
            motor=motor,
            metadata=metadata if kind == KIND_INTERPRETER else {},
            **settings,
        ),
    )
    if kind == KIND_INTERPRETER:
        return im_spec
    here = f"{where}: program_module"
    pm_data = _object(data["program_module"], here)
    _fields(pm_data, here, ["network", "program_neurons", "substeps"], ["camera"])
    pm = _network_from_dict(pm_data["network"], f"{here}.network")
    neurons = pm_data["program_neurons"]
    if not isinstance(neurons, list):
        raise MbnInputError(f"{here}.program_neurons: expected a list of integers, got {neurons!r}")
    neurons_t = tuple(_integer(i, f"{here}.program_neurons") for i in neurons)
    pm_substeps = _integer(pm_data["substeps"], f"{here}.substeps")
    camera = CameraConfig()
    if "camera" in pm_data:
        cam = _object(pm_data["camera"], f"{here}.camera")
        _fields(cam, f"{here}.camera", ["fov_deg", "range"])
        fov = _number(cam["fov_deg"], f"{here}.camera.fov_deg")
        rng = _number(cam["range"], f"{here}.camera.range")
        camera = _build(f"{here}.camera", lambda: CameraConfig(fov_deg=fov, range=rng))
    return _build(
        where,
        lambda: MBNControllerSpec(
            interpreter_spec=im_spec,
            program_module=pm,
            program_neurons=neurons_t,
            pm_substeps=pm_substeps,
            camera=camera,
            metadata=metadata,
        ),
    )


def _build(where: str, make: Callable[[], Any]) -> Any:
    """Construct a spec, prefixing its validation errors with ``where``."""
    try:
        return make()
    except MbnInputError as exc:
        raise MbnInputError(f"{where}: {exc}") from None


def save_controller(path: str | Path, spec: ControllerSpec) -> None:
    """Write a controller file atomically.

    The JSON form is checked to load back first, so a spec that could not be read (or metadata
    that is not JSON) raises :class:`MbnInputError` and leaves ``path`` as it was.
    """
    from mbn.io import write_json_atomic

    data = controller_to_dict(spec)
    try:
        text = json.dumps(data, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise MbnInputError(f"{path}: cannot be written as JSON ({exc})") from None
    controller_from_dict(json.loads(text), where=str(path))
    write_json_atomic(path, data)


def read_controller_spec(path: str | Path) -> ControllerSpec:
    """Read and validate a controller file (errors name the file, and the line for bad JSON)."""
    from mbn.io import read_json

    return controller_from_dict(read_json(path), where=str(path))


# --------------------------------------------------------------------------------------------
# Running a controller
# --------------------------------------------------------------------------------------------


class MBNControllerState(NamedTuple):
    """The MBN's state for one robot: the program module (network and potentials) and the
    interpreter (network and potentials)."""

    pm: CTRNN
    pm_y: Array
    im: CTRNN
    im_y: Array


def make_mbn_controller(
    *,
    program_neurons: Sequence[int],
    dt: float = 0.1,
    substeps: int = NETWORK_SUBSTEPS,
    pm_substeps: int = 4,
    motor: MotorMap | None = None,
    method: str = "euler",
) -> Callable[[MBNControllerState, Any], tuple[MBNControllerState, tuple[Array, Array]]]:
    """The MBN as a controller ``(state, obs) -> (state, (v, w))`` for one robot.

    Each step the program module integrates the camera reading ``[camera == 1, camera == 2]``
    for ``dt`` (``pm_substeps`` Euler steps); the firing rates of ``program_neurons`` are the
    program; then the interpreter integrates I1..I3 and that program for ``dt`` as
    :func:`mbn.control.ctrnn.interpreter_controller` does (``substeps`` steps of ``method``).
    """
    if pm_substeps < 1:
        raise MbnInputError(f"pm_substeps must be >= 1, got {pm_substeps}")
    index = jnp.asarray(tuple(program_neurons), jnp.int32)
    h = dt / pm_substeps
    interpret = interpreter_controller(dt=dt, substeps=substeps, motor=motor, method=method)

    def control(
        state: MBNControllerState, obs: Any
    ) -> tuple[MBNControllerState, tuple[Array, Array]]:
        dtype = state.pm_y.dtype
        camera = jnp.stack([obs.camera == 1, obs.camera == 2], axis=-1).astype(dtype)
        y = state.pm_y
        for _ in range(pm_substeps):
            y = euler_step(state.pm, y, camera, h)
        program = firing_rate(state.pm, y)[..., index]
        im_state, vw = interpret(ProgrammedState(state.im, state.im_y, program), obs)
        return MBNControllerState(state.pm, y, state.im, im_state.y), vw

    return control


def _batched(tree: Any, n: int) -> Any:
    return jax.tree.map(lambda a: jnp.broadcast_to(a, (n, *a.shape)), tree)


@dataclass(frozen=True, eq=False)
class LoadedController:
    """A controller ready to run (:func:`mbn.experiments.trials.run_trials`).

    Attributes:
        kind: the file's kind (:data:`KINDS`).
        controller: ``(state, obs) -> (state, (v, w))`` for one robot.
        initial_state: ``n -> `` the batched initial state of ``n`` robots (potentials at 0).
        sensors: the sonars to cast and their normalisation.
        dt: the robot step (s).
        needs_camera: whether the controller reads the camera (the whole MBN).
        camera: the camera settings it reads (None when it reads none).
        programs: the file's named programs (empty for a plain CTRNN).
        program: the program in use (None for a plain CTRNN or the whole MBN).
        behavior: the behaviour a plain CTRNN file declares (else None).
        spec: the parsed file.
    """

    kind: str
    controller: Controller
    initial_state: Callable[[int], Any]
    sensors: SensorConfig
    dt: float
    needs_camera: bool
    camera: CameraConfig | None
    programs: dict[str, tuple[float, ...]]
    program: str | None
    behavior: str | None
    spec: ControllerSpec


def _programs_of(spec: InterpreterControllerSpec) -> dict[str, tuple[float, ...]]:
    return {name: tuple(float(v) for v in p) for name, p in spec.programs.items()}


def _choose_program(
    programs: Mapping[str, tuple[float, ...]], program: str | None, kind: str, where: str
) -> str:
    names = ", ".join(programs) or "none"
    if program is None:
        if len(programs) == 1:
            return next(iter(programs))
        raise MbnInputError(f"{where}: choose a program of this {kind} controller ({names})")
    if program not in programs:
        raise MbnInputError(f"{where}: no program {program!r} (the file has: {names})")
    return program


def make_controller(
    spec: ControllerSpec, program: str | None = None, *, where: str = "controller"
) -> LoadedController:
    """A :class:`LoadedController` for a spec.

    ``program``: for an interpreter, the name of the program to run (may be omitted when there
    is only one); for an MBN, None runs the whole MBN (program module and camera) and a name runs
    the interpreter alone with that stored program; for a plain CTRNN it must be None.
    """
    if isinstance(spec, CTRNNControllerSpec):
        if program is not None:
            raise MbnInputError(
                f"{where}: a plain CTRNN controller has no programs (got program {program!r})"
            )
        net = spec.net
        ctrnn_fn = ctrnn_controller(
            dt=spec.dt, substeps=spec.substeps, motor=spec.motor, method=spec.method
        )

        def ctrnn_initial(n: int) -> CTRNNState:
            return CTRNNState(_batched(net, n), jnp.zeros((n, net.num_neurons), net.dtype))

        return LoadedController(
            kind=KIND_CTRNN,
            controller=ctrnn_fn,
            initial_state=ctrnn_initial,
            sensors=spec.sensors,
            dt=spec.dt,
            needs_camera=False,
            camera=None,
            programs={},
            program=None,
            behavior=spec.behavior,
            spec=spec,
        )
    if isinstance(spec, MBNControllerSpec) and program is None:
        im_spec = spec.interpreter_spec
        im, pm = im_spec.interpreter.net, spec.program_module
        mbn_fn = make_mbn_controller(
            program_neurons=spec.program_neurons,
            dt=im_spec.dt,
            substeps=im_spec.substeps,
            pm_substeps=spec.pm_substeps,
            motor=im_spec.motor,
            method=im_spec.method,
        )

        def mbn_initial(n: int) -> MBNControllerState:
            return MBNControllerState(
                _batched(pm, n),
                jnp.zeros((n, pm.num_neurons), pm.dtype),
                _batched(im, n),
                jnp.zeros((n, im.num_neurons), im.dtype),
            )

        return LoadedController(
            kind=KIND_MBN,
            controller=mbn_fn,
            initial_state=mbn_initial,
            sensors=im_spec.sensors,
            dt=im_spec.dt,
            needs_camera=True,
            camera=spec.camera,
            programs=_programs_of(im_spec),
            program=None,
            behavior=None,
            spec=spec,
        )
    if isinstance(spec, (InterpreterControllerSpec, MBNControllerSpec)):
        kind = KIND_INTERPRETER if isinstance(spec, InterpreterControllerSpec) else KIND_MBN
        im_spec = spec if isinstance(spec, InterpreterControllerSpec) else spec.interpreter_spec
        programs = _programs_of(im_spec)
        name = _choose_program(programs, program, kind, where)
        interp_net = im_spec.interpreter.net
        values = jnp.asarray(programs[name], interp_net.dtype)
        im_fn = interpreter_controller(
            dt=im_spec.dt, substeps=im_spec.substeps, motor=im_spec.motor, method=im_spec.method
        )

        def im_initial(n: int) -> ProgrammedState:
            return ProgrammedState(
                _batched(interp_net, n),
                jnp.zeros((n, interp_net.num_neurons), interp_net.dtype),
                jnp.broadcast_to(values, (n, values.shape[0])),
            )

        return LoadedController(
            kind=kind,
            controller=im_fn,
            initial_state=im_initial,
            sensors=im_spec.sensors,
            dt=im_spec.dt,
            needs_camera=False,
            camera=None,
            programs=programs,
            program=name,
            behavior=None,
            spec=spec,
        )
    raise MbnInputError(f"{where}: not a controller spec: {type(spec).__name__}")


def load_controller(path: str | Path, program: str | None = None) -> LoadedController:
    """Read a controller file and make it ready to run (see :func:`make_controller` for
    ``program``). Errors are one line naming the file."""
    return make_controller(read_controller_spec(path), program, where=str(path))
