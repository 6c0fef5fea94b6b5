"""Controller files as JSON: :func:`controller_to_dict`, :func:`controller_from_dict`,
:func:`save_controller` (atomic, checked to load back) and :func:`read_controller_spec`.

The only code that knows the file format (``docs/controllers.md``): the header every controller
file starts with, and the fields of ``mbn``'s kinds (:func:`ctrnn_body` and
:func:`ctrnn_from_body`, ... , which :mod:`mbn.controllers.builtin` registers); a file's kind is
found in the registry of kinds (:mod:`mbn.controllers.kinds`), where a kind kept outside ``mbn``
reads and writes its own fields. Every error is one line naming the file and the field. The
objects are :mod:`mbn.controllers.spec`.
"""

from __future__ import annotations

import dataclasses
import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax.numpy as jnp
import numpy as np

from mbn._version import __version__
from mbn.control.ctrnn import MotorMap
from mbn.controllers.kinds import (
    HEADER_FIELDS,
    OPTIONAL_HEADER_FIELDS,
    ControllerKind,
    check_body,
    controller_kind,
    kind_of,
    registered_kinds,
)
from mbn.controllers.spec import (
    FORMAT_VERSION,
    MULTIPLIER_KIND,
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    MBNControllerSpec,
    PMInitial,
    SwitchedControllerSpec,
)
from mbn.errors import MbnInputError
from mbn.io import (
    check_fields,
    expect_int,
    expect_int_list,
    expect_number,
    expect_number_list,
    expect_object,
    read_json,
    write_json_atomic,
)
from mbn.networks.ctrnn import CTRNN, firing_rate
from mbn.networks.programmable import Connection, Interpreter, weights_digest
from mbn.provenance import provenance
from mbn.world.engine import CameraConfig
from mbn.world.sensors import SensorConfig

__all__ = [
    "controller_from_dict",
    "controller_to_dict",
    "ctrnn_body",
    "ctrnn_from_body",
    "interpreter_body",
    "interpreter_from_body",
    "mbn_body",
    "mbn_from_body",
    "read_controller_spec",
    "save_controller",
    "switched_body",
    "switched_from_body",
]

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
    """The fields every controller file starts with, and the code and software that wrote it
    (``provenance``: :func:`mbn.provenance.provenance`)."""
    return {
        "kind": kind,
        "format_version": FORMAT_VERSION,
        "mbn_version": __version__,
        "provenance": provenance(),
    }


def _interpreter_fields(spec: InterpreterControllerSpec) -> dict[str, Any]:
    return {
        "interpreter": _interpreter_to_dict(spec.interpreter),
        "programs": {name: list(p) for name, p in spec.programs.items()},
        "sensors": _sensors_to_dict(spec.sensors),
        "motor": _motor_to_dict(spec.motor),
        "dt": spec.dt,
        "substeps": spec.substeps,
        "method": spec.method,
        # written only when not the default, so that older files read and write unchanged
        **({"simulation": spec.simulation} if spec.simulation != "dense" else {}),
    }


def _camera_to_dict(camera: CameraConfig) -> dict[str, float]:
    return {"fov_deg": camera.fov_deg, "range": camera.range}


def _camera_from_dict(value: Any, here: str) -> CameraConfig:
    """A camera's settings; ``here`` names the field in errors."""
    cam = expect_object(value, here)
    check_fields(cam, here, ["fov_deg", "range"])
    fov = expect_number(cam["fov_deg"], f"{here}.fov_deg")
    rng = expect_number(cam["range"], f"{here}.range")
    return _build(here, lambda: CameraConfig(fov_deg=fov, range=rng))


def _rule_list(value: Any, where: str) -> tuple[str, ...]:
    if not isinstance(value, list) or not all(isinstance(r, str) for r in value):
        raise MbnInputError(f"{where}: expected a list of rule names")
    return tuple(value)


def ctrnn_body(spec: CTRNNControllerSpec) -> dict[str, Any]:
    """The fields of a ``mbn.controller.ctrnn`` file after the header."""
    return {
        "behavior": spec.behavior,
        "network": spec.net.to_dict(),
        "sensors": _sensors_to_dict(spec.sensors),
        "motor": _motor_to_dict(spec.motor),
        "dt": spec.dt,
        "substeps": spec.substeps,
        "method": spec.method,
        # written only for a controller that reads the camera, so that followers' files
        # read and write unchanged
        **(
            {
                "tile_rules": list(spec.tile_rules),
                "camera": _camera_to_dict(spec.camera),
            }
            if spec.tile_rules is not None
            else {}
        ),
        "metadata": dict(spec.metadata),
    }


def interpreter_body(spec: InterpreterControllerSpec) -> dict[str, Any]:
    """The fields of a ``mbn.controller.interpreter`` file after the header."""
    return {**_interpreter_fields(spec), "metadata": dict(spec.metadata)}


def mbn_body(spec: MBNControllerSpec) -> dict[str, Any]:
    """The fields of a ``mbn.controller.mbn`` file after the header."""
    pm: dict[str, Any] = {
        "network": spec.program_module.to_dict(),
        "program_neurons": list(spec.program_neurons),
        "substeps": spec.pm_substeps,
        "camera": _camera_to_dict(spec.camera),
    }
    # written only when not the paper's, so that older files read and write unchanged
    if spec.tile_rules != ("right", "left"):
        pm["tile_rules"] = list(spec.tile_rules)
    if spec.readout is not None:
        pm["readout"] = [list(row) for row in spec.readout]
    if spec.initial is not None:
        pm["initial"] = {
            "rule": spec.initial.rule,
            "potentials": list(spec.initial.potentials),
            "program": _initial_program(spec.program_module, spec.program_neurons, spec.initial),
        }
    return {
        **_interpreter_fields(spec.interpreter_spec),
        "program_module": pm,
        "metadata": dict(spec.metadata),
    }


def switched_body(spec: SwitchedControllerSpec) -> dict[str, Any]:
    """The fields of a ``mbn.controller.switched`` file after the header."""
    return {
        "mode": spec.mode,
        "networks": {rule: net.to_dict() for rule, net in spec.networks.items()},
        "tile_rules": list(spec.tile_rules),
        "initial": spec.initial,
        "camera": _camera_to_dict(spec.camera),
        "sensors": _sensors_to_dict(spec.sensors),
        "motor": _motor_to_dict(spec.motor),
        "dt": spec.dt,
        "substeps": spec.substeps,
        "method": spec.method,
        "metadata": dict(spec.metadata),
    }


def controller_to_dict(spec: Any) -> dict[str, Any]:
    """The self-describing JSON form of a controller spec (see ``docs/controllers.md``): the
    header, then the fields its kind writes (:meth:`ControllerKind.to_dict
    <mbn.controllers.kinds.ControllerKind.to_dict>`)."""
    kind = kind_of(spec)
    if kind is None:
        raise MbnInputError(
            f"not a controller spec: {type(spec).__name__} (expected {_spec_types()})"
        )
    body = kind.to_dict(spec)
    clash = [k for k in (*HEADER_FIELDS, *OPTIONAL_HEADER_FIELDS) if k in body]
    if clash:
        raise MbnInputError(
            f"controller kind {kind.name}: its fields may not include the header's "
            f"({', '.join(clash)})"
        )
    return {**_header(kind.name), **body}


#: How far a file's ``program_module.initial.program`` may lie from the firing rates of its
#: potentials (it is written from them; the margin covers float32 and printing).
INITIAL_PROGRAM_TOL = 1e-4


def _initial_program(
    pm: CTRNN, program_neurons: tuple[int, ...], initial: PMInitial
) -> list[float]:
    """The program the PM sends from its initial potentials (the firing rates of its program
    neurons), written beside them for the reader and checked on reading."""
    y = jnp.asarray(initial.potentials, pm.dtype)
    rates = np.asarray(firing_rate(pm, y), np.float64)[list(program_neurons)]
    return [round(float(v), 6) for v in rates]


def _initial_from_dict(
    value: Any, where: str, pm: CTRNN, program_neurons: tuple[int, ...]
) -> PMInitial:
    data = expect_object(value, where)
    check_fields(data, where, ["rule", "potentials"], ["program"])
    potentials = expect_number_list(data["potentials"], f"{where}.potentials")
    initial: PMInitial = _build(
        where, lambda: PMInitial(rule=data["rule"], potentials=tuple(potentials))
    )
    if len(initial.potentials) != pm.num_neurons:
        raise MbnInputError(
            f"{where}.potentials: the program module has {pm.num_neurons} neurons, got "
            f"{len(initial.potentials)} potentials"
        )
    if "program" in data:
        program = np.asarray(expect_number_list(data["program"], f"{where}.program"))
        sent = np.asarray(_initial_program(pm, program_neurons, initial))
        if program.shape != sent.shape or np.max(np.abs(program - sent)) > INITIAL_PROGRAM_TOL:
            raise MbnInputError(
                f"{where}.program {program.tolist()} is not what its potentials send "
                f"({sent.tolist()})"
            )
    return initial


def _sensors_from_dict(value: Any, where: str) -> SensorConfig:
    data = expect_object(value, f"{where}: sensors")
    check_fields(data, f"{where}: sensors", ["sonars"], ["normalization", "near", "far"])
    sonars = expect_int_list(data["sonars"], f"{where}: sensors.sonars")
    defaults = SensorConfig()
    try:
        return SensorConfig(
            sonars=tuple(sonars),
            normalization=data.get("normalization", defaults.normalization),
            near=expect_number(data.get("near", defaults.near), f"{where}: sensors.near"),
            far=expect_number(data.get("far", defaults.far), f"{where}: sensors.far"),
        )
    except MbnInputError as exc:
        if str(exc).startswith(where):
            raise
        raise MbnInputError(f"{where}: sensors: {exc}") from None


def _motor_from_dict(value: Any, where: str) -> MotorMap:
    data = expect_object(value, f"{where}: motor")
    check_fields(data, f"{where}: motor", ["speed_neuron", "turn_neuron"], ["v_max", "w_max"])
    defaults = MotorMap()
    speed = expect_int(data["speed_neuron"], f"{where}: motor.speed_neuron")
    turn = expect_int(data["turn_neuron"], f"{where}: motor.turn_neuron")
    v_max = expect_number(data.get("v_max", defaults.v_max), f"{where}: motor.v_max")
    w_max = expect_number(data.get("w_max", defaults.w_max), f"{where}: motor.w_max")
    try:
        return MotorMap(speed_neuron=speed, turn_neuron=turn, v_max=v_max, w_max=w_max)
    except MbnInputError as exc:
        raise MbnInputError(f"{where}: motor: {exc}") from None


def _network_from_dict(value: Any, where: str) -> CTRNN:
    data = expect_object(value, where)
    check_fields(data, where, ["W", "WE", "tau"], ["bias", "gain"])
    net = CTRNN.from_dict(data, where=where)
    if net.W.ndim != 2:
        raise MbnInputError(f"{where}: expected one network, got W of shape {tuple(net.W.shape)}")
    return net


def _interpreter_from_dict(value: Any, where: str) -> Interpreter:
    here = f"{where}: interpreter"
    data = expect_object(value, here)
    keys = ["net", "connections", "lower", "upper", "num_original", "num_data_inputs"]
    check_fields(data, here, [*keys, "mul_size", "mul_output"])
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
        bounds[name] = expect_number_list(data[name], f"{here}.{name}")
    ints = {
        name: expect_int(data[name], f"{here}.{name}")
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
        "dt": expect_number(data["dt"], f"{where}: dt"),
        "substeps": expect_int(data["substeps"], f"{where}: substeps"),
        "method": data["method"],
    }


def _spec_types() -> str:
    """The registered kinds' spec classes, for a message: ``A, B or C``."""
    names = [k.spec_type.__name__ for k in registered_kinds().values()]
    return ", ".join(names[:-1]) + " or " + names[-1] if len(names) > 1 else "".join(names)


def _check_header(data: Any, where: str) -> ControllerKind:
    known = ", ".join(registered_kinds())
    if not isinstance(data, dict):
        raise MbnInputError(
            f"{where}: not a controller file (a JSON {type(data).__name__}, expected an object "
            f"with a 'kind', one of {known})"
        )
    name = data.get("kind")
    if name == MULTIPLIER_KIND:
        raise MbnInputError(
            f"{where}: is a multiplier, not a controller (kind {name!r}; expected one of {known})"
        )
    kind = controller_kind(name) if isinstance(name, str) else None
    if kind is None:
        raise MbnInputError(
            f"{where}: not a controller file (kind {name!r}, expected one of "
            f"{', '.join(registered_kinds())})"
        )
    if "format_version" not in data:
        raise MbnInputError(f"{where}: missing field 'format_version'")
    version = data["format_version"]
    if version != FORMAT_VERSION or isinstance(version, bool):
        raise MbnInputError(
            f"{where}: format_version {version!r} is not supported (this mbn reads "
            f"{FORMAT_VERSION})"
        )
    return kind


def controller_from_dict(data: Any, *, where: str = "controller") -> Any:
    """Parse and validate the JSON form of a controller (:func:`controller_to_dict`): the header,
    then the rest by its kind (:meth:`ControllerKind.from_dict
    <mbn.controllers.kinds.ControllerKind.from_dict>`).

    Raises:
        MbnInputError: one line naming ``where`` and what is wrong.
    """
    return _check_header(data, where).from_dict(data, where)


#: The optional fields of every built-in kind's file besides the header's.
_OPTIONAL = ["metadata"]
#: The fields every built-in kind's file has after the header.
_COMMON = ["sensors", "motor", "dt", "substeps", "method"]


def ctrnn_from_body(data: dict[str, Any], where: str) -> CTRNNControllerSpec:
    """The spec of a ``mbn.controller.ctrnn`` file (its header checked)."""
    check_body(
        data,
        where,
        ["network", *_COMMON],
        [*_OPTIONAL, "behavior", "tile_rules", "camera"],
    )
    if ("tile_rules" in data) != ("camera" in data):
        raise MbnInputError(f"{where}: tile_rules and camera go together (the camera it reads)")
    tiles = _rule_list(data["tile_rules"], f"{where}: tile_rules") if "tile_rules" in data else None
    camera = (
        _camera_from_dict(data["camera"], f"{where}: camera")
        if "camera" in data
        else CameraConfig()
    )
    net = _network_from_dict(data["network"], f"{where}: network")
    sensors = _sensors_from_dict(data["sensors"], where)
    motor = _motor_from_dict(data["motor"], where)
    settings = _run_settings(data, where)
    metadata = data.get("metadata", {})
    behavior = data.get("behavior")
    spec: CTRNNControllerSpec = _build(
        where,
        lambda: CTRNNControllerSpec(
            net=net,
            sensors=sensors,
            motor=motor,
            behavior=behavior,
            metadata=metadata,
            tile_rules=tiles,
            camera=camera,
            **settings,
        ),
    )
    return spec


def switched_from_body(data: dict[str, Any], where: str) -> SwitchedControllerSpec:
    """The spec of a ``mbn.controller.switched`` file (its header checked)."""
    check_body(
        data,
        where,
        ["mode", "networks", "tile_rules", "camera", *_COMMON],
        [*_OPTIONAL, "initial"],
    )
    mode = data["mode"]
    tiles = _rule_list(data["tile_rules"], f"{where}: tile_rules")
    networks = expect_object(data["networks"], f"{where}: networks")
    nets = {
        rule: _network_from_dict(value, f"{where}: networks.{rule}")
        for rule, value in networks.items()
    }
    initial = data.get("initial")
    if initial is not None and not isinstance(initial, str):
        raise MbnInputError(f"{where}: initial: expected a rule name or null, got {initial!r}")
    camera = _camera_from_dict(data["camera"], f"{where}: camera")
    sensors = _sensors_from_dict(data["sensors"], where)
    motor = _motor_from_dict(data["motor"], where)
    settings = _run_settings(data, where)
    metadata = data.get("metadata", {})
    spec: SwitchedControllerSpec = _build(
        where,
        lambda: SwitchedControllerSpec(
            networks=nets,
            mode=mode,
            tile_rules=tiles,
            initial=initial,
            camera=camera,
            sensors=sensors,
            motor=motor,
            metadata=metadata,
            **settings,
        ),
    )
    return spec


def _interpreter_spec_from(
    data: dict[str, Any], where: str, *, alone: bool
) -> InterpreterControllerSpec:
    """The interpreter of an interpreter file (``alone``) or of an MBN file, with the file's
    fields checked (an MBN file's ``program_module`` is read by :func:`mbn_from_body`)."""
    body = ["interpreter", "programs", *_COMMON]
    check_body(
        data, where, body if alone else [*body, "program_module"], [*_OPTIONAL, "simulation"]
    )
    simulation = data.get("simulation", "dense")
    interp = _interpreter_from_dict(data["interpreter"], where)
    programs = expect_object(data["programs"], f"{where}: programs")
    if alone and not programs:
        raise MbnInputError(f"{where}: programs: an interpreter file needs at least one program")
    sensors = _sensors_from_dict(data["sensors"], where)
    motor = _motor_from_dict(data["motor"], where)
    settings = _run_settings(data, where)
    metadata = data.get("metadata", {})
    im_spec: InterpreterControllerSpec = _build(
        where,
        lambda: InterpreterControllerSpec(
            interpreter=interp,
            programs=programs,
            sensors=sensors,
            motor=motor,
            metadata=metadata if alone else {},
            simulation=simulation,
            **settings,
        ),
    )
    _check_recorded_digest(data, im_spec.interpreter, where)
    return im_spec


def interpreter_from_body(data: dict[str, Any], where: str) -> InterpreterControllerSpec:
    """The spec of a ``mbn.controller.interpreter`` file (its header checked)."""
    return _interpreter_spec_from(data, where, alone=True)


def mbn_from_body(data: dict[str, Any], where: str) -> MBNControllerSpec:
    """The spec of a ``mbn.controller.mbn`` file (its header checked)."""
    im_spec = _interpreter_spec_from(data, where, alone=False)
    metadata = data.get("metadata", {})
    here = f"{where}: program_module"
    pm_data = expect_object(data["program_module"], here)
    check_fields(
        pm_data,
        here,
        ["network", "program_neurons", "substeps"],
        ["camera", "initial", "tile_rules", "readout"],
    )
    pm = _network_from_dict(pm_data["network"], f"{here}.network")
    neurons_t = tuple(expect_int_list(pm_data["program_neurons"], f"{here}.program_neurons"))
    pm_substeps = expect_int(pm_data["substeps"], f"{here}.substeps")
    camera = (
        _camera_from_dict(pm_data["camera"], f"{here}.camera")
        if "camera" in pm_data
        else CameraConfig()
    )
    tile_rules: tuple[str, ...] = ("right", "left")
    if "tile_rules" in pm_data:
        tile_rules = _rule_list(pm_data["tile_rules"], f"{here}.tile_rules")
    readout = None
    if "readout" in pm_data:
        rows = pm_data["readout"]
        if not isinstance(rows, list):
            raise MbnInputError(f"{where}: {here}.readout: expected a list of rows")
        readout = [expect_number_list(r, f"{here}.readout[{i}]") for i, r in enumerate(rows)]
    spec: MBNControllerSpec = _build(
        where,
        lambda: MBNControllerSpec(
            interpreter_spec=im_spec,
            program_module=pm,
            program_neurons=neurons_t,
            pm_substeps=pm_substeps,
            camera=camera,
            metadata=metadata,
            readout=readout,
            tile_rules=tile_rules,
        ),
    )
    if "initial" not in pm_data:  # files written before the field: the PM starts at rest
        return spec
    initial = _initial_from_dict(pm_data["initial"], f"{here}.initial", pm, neurons_t)
    started: MBNControllerSpec = _build(where, lambda: dataclasses.replace(spec, initial=initial))
    return started


_SHA256 = re.compile(r"[0-9a-fA-F]{64}")


def _check_recorded_digest(data: dict[str, Any], interp: Interpreter, where: str) -> None:
    """Refuse an interpreter or MBN file whose ``metadata.sha256`` (the digest of the
    interpreter's weights a run records, :meth:`Interpreter.digest`) is not that of the weights
    it holds: they were changed since it was written. The digest is taken of the file's values
    (float64), as the writer took it of the same values, in whatever precision it is read."""
    metadata = data.get("metadata")
    if not isinstance(metadata, dict) or "sha256" not in metadata:
        return
    recorded = metadata["sha256"]
    if not isinstance(recorded, str) or not _SHA256.fullmatch(recorded):
        raise MbnInputError(
            f"{where}: metadata.sha256: expected the sha256 of the interpreter's weights (64 "
            f"hexadecimal digits), got {repr(recorded)[:80]}"
        )
    net = data["interpreter"]["net"]
    n = interp.net.num_neurons

    def vector(name: str, default: float) -> np.ndarray:
        return np.broadcast_to(np.asarray(net.get(name, default), np.float64), (n,))

    got = weights_digest(
        [net["W"], net["WE"], vector("tau", 1.0), vector("bias", 0.0), vector("gain", 1.0)],
        data["interpreter"]["lower"],
        data["interpreter"]["upper"],
        interp.connections,
    )
    if got != recorded.lower():
        raise MbnInputError(
            f"{where}: the interpreter's sha256 is {got[:12]}…, not the {recorded[:12]}… its "
            "metadata records: its weights were changed since the file was written"
        )


def _build(where: str, make: Callable[[], Any]) -> Any:
    """Construct a spec, prefixing its validation errors with ``where``."""
    try:
        return make()
    except MbnInputError as exc:
        raise MbnInputError(f"{where}: {exc}") from None


def save_controller(path: str | Path, spec: Any) -> None:
    """Write a controller file atomically.

    The JSON form is checked to load back first, so a spec that could not be read (or metadata
    that is not JSON) raises :class:`MbnInputError` and leaves ``path`` as it was.
    """
    data = controller_to_dict(spec)
    try:
        text = json.dumps(data, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise MbnInputError(f"{path}: cannot be written as JSON ({exc})") from None
    controller_from_dict(json.loads(text), where=str(path))
    write_json_atomic(path, data)


def read_controller_spec(path: str | Path) -> Any:
    """Read and validate a controller file (errors name the file, and the line for bad JSON)."""
    return controller_from_dict(read_json(path), where=str(path))
