"""Controller files: round trips of the three kinds, validation, and the MBN controller."""

from __future__ import annotations

import copy
import json
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.control.ctrnn import MotorMap
from mbn.controllers import (
    KIND_CTRNN,
    KIND_INTERPRETER,
    KIND_MBN,
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    MBNControllerSpec,
    controller_to_dict,
    load_controller,
    make_controller,
    save_controller,
)
from mbn.errors import MbnInputError
from mbn.networks.ctrnn import make_ctrnn
from mbn.networks.multiplier import load_default, multiplier_to_dict
from mbn.networks.programmable import build_interpreter, differing_connections
from mbn.world.rollout import Observation, map_controller
from mbn.world.sensors import PAPER_SONARS, SensorConfig

K = 3  # programmable connections of the test interpreter


def _nets():
    rng = np.random.default_rng(0)
    W = rng.uniform(-5, 5, (3, 3))
    WE = rng.uniform(-5, 5, (3, 3))
    a = make_ctrnn(W, WE, 0.5, bias=rng.uniform(-1, 1, 3))
    W2, WE2 = W.copy(), WE.copy()
    W2[1, 2], WE2[1, 0], WE2[2, 1] = -W[1, 2], WE[1, 0] + 3, WE[2, 1] - 4
    b = make_ctrnn(W2, WE2, 0.5, bias=np.asarray(a.bias))
    return a, b


@pytest.fixture(scope="session")
def ctrnn_spec():
    net, _ = _nets()
    sensors = SensorConfig(sonars=(*PAPER_SONARS, 11), normalization="distance", far=3.0)
    return CTRNNControllerSpec(
        net,
        sensors=sensors,
        motor=MotorMap(speed_neuron=0, turn_neuron=2, v_max=0.4, w_max=0.8),
        dt=0.1,
        substeps=5,
        method="rk4",
        behavior="right",
        metadata={"seed": 3, "note": "test"},
    )


@pytest.fixture(scope="session")
def interpreter_spec():
    a, b = _nets()
    interp = build_interpreter(a, differing_connections(a, b), load_default())
    assert interp.num_programs == K
    programs = {
        "right": np.asarray(interp.program_of(a)).tolist(),
        "left": np.asarray(interp.program_of(b)).tolist(),
    }
    return InterpreterControllerSpec(interp, programs, metadata={"source": "test"})


def _pm_without_memory(programs, dt=0.1, pm_substeps=4):
    """A program module whose program after one robot step is exactly ``sigmoid(WE cam)``: no
    recurrence and tau equal to the Euler step, so each step sets ``y`` to its drive."""
    right = np.asarray(programs["right"])
    left = np.asarray(programs["left"])
    logit = lambda p: np.log(p / (1 - p))  # noqa: E731
    WE = np.stack([logit(right), logit(left)], -1)
    return make_ctrnn(np.zeros((K, K)), WE, dt / pm_substeps)


@pytest.fixture(scope="session")
def mbn_spec(interpreter_spec):
    pm = _pm_without_memory(interpreter_spec.programs)
    return MBNControllerSpec(interpreter_spec, pm, (0, 1, 2), pm_substeps=4, metadata={"k": [1]})


def _obs(n, camera=0, seed=1):
    rng = np.random.default_rng(seed)
    return Observation(
        ranges=jnp.asarray(rng.uniform(0.2, 3, (n, 11))),
        S=jnp.asarray(rng.uniform(0, 1, (n, 11))),
        inputs=jnp.asarray(rng.uniform(0, 1, (n, 3))),
        camera=jnp.full((n,), camera, jnp.int32),
        blobs=jnp.zeros((n,), jnp.int32),
        tile=jnp.zeros((n,), jnp.int32),
        stalled=jnp.zeros((n,), bool),
        t=jnp.zeros((n,)),
    )


_STEPS: dict = {}  # one compiled step per controller function
_INTERPRETERS: dict = {}  # the test interpreter's controllers, by program (compiled once)


def _drive(loaded, cameras, n=2):
    """(v, w) of ``n`` robots over steps with the given camera readings (fixed sonar inputs)."""
    state = loaded.initial_state(n)
    if loaded.controller not in _STEPS:
        _STEPS[loaded.controller] = jax.jit(map_controller(loaded.controller, state))
    step = _STEPS[loaded.controller]
    out = []
    for c in cameras:
        state, (v, w) = step(state, _obs(n, camera=c))
        out.append((np.asarray(v), np.asarray(w)))
    return state, np.array(out)


# --------------------------------------------------------------------------------------------
# Round trips
# --------------------------------------------------------------------------------------------


def test_ctrnn_round_trip_drives_identically(tmp_path, ctrnn_spec):
    path = tmp_path / "rf.json"
    save_controller(path, ctrnn_spec)
    data = json.loads(path.read_text())
    assert data["kind"] == KIND_CTRNN and data["format_version"] == 1 and "mbn_version" in data
    assert data["network"]["tau"] == [0.5, 0.5, 0.5]
    assert data["sensors"]["sonars"] == [*PAPER_SONARS, 11]
    loaded = load_controller(path)
    assert loaded.kind == KIND_CTRNN and loaded.behavior == "right" and not loaded.needs_camera
    assert loaded.programs == {} and loaded.program is None
    assert loaded.sensors == ctrnn_spec.sensors and loaded.dt == 0.1
    assert loaded.spec.metadata == {"seed": 3, "note": "test"}
    _, ours = _drive(make_controller(ctrnn_spec), [0, 0, 0])
    _, theirs = _drive(loaded, [0, 0, 0])
    np.testing.assert_array_equal(ours, theirs)
    assert np.all(ours[:, 0] >= 0) and np.all(ours[:, 0] <= 0.4)  # v = v_max sigma(.)
    # the file is stable: saving what was loaded writes the same JSON
    again = tmp_path / "again.json"
    save_controller(again, loaded.spec)
    assert json.loads(again.read_text()) == data


def test_interpreter_round_trip_drives_identically_with_each_program(tmp_path, interpreter_spec):
    path = tmp_path / "im.json"
    save_controller(path, interpreter_spec)
    data = json.loads(path.read_text())
    assert data["kind"] == KIND_INTERPRETER
    assert data["interpreter"]["connections"] == [
        str(c) for c in interpreter_spec.interpreter.connections
    ]
    assert set(data["programs"]) == {"right", "left"}
    outputs = {}
    for name in ("right", "left"):
        loaded = load_controller(path, program=name)
        assert loaded.kind == KIND_INTERPRETER and loaded.program == name
        assert loaded.programs == interpreter_spec.programs
        ours_c = _INTERPRETERS.setdefault(name, make_controller(interpreter_spec, name))
        _, ours = _drive(ours_c, [0, 0])
        _, theirs = _drive(loaded, [0, 0])
        np.testing.assert_array_equal(ours, theirs)
        outputs[name] = theirs
    assert not np.allclose(outputs["right"], outputs["left"])


def test_mbn_round_trip_drives_identically(tmp_path, mbn_spec):
    path = tmp_path / "mbn.json"
    save_controller(path, mbn_spec)
    data = json.loads(path.read_text())
    assert data["kind"] == KIND_MBN
    assert data["program_module"]["program_neurons"] == [0, 1, 2]
    assert data["program_module"]["substeps"] == 4
    assert data["program_module"]["camera"] == {"fov_deg": 60.0, "range": 3.0}
    loaded = load_controller(path)
    assert loaded.kind == KIND_MBN and loaded.needs_camera and loaded.program is None
    assert loaded.camera == mbn_spec.camera
    cameras = [0, 1, 1, 0, 2, 2]
    _, ours = _drive(make_controller(mbn_spec), cameras)
    _, theirs = _drive(loaded, cameras)
    np.testing.assert_array_equal(ours, theirs)
    # with a program name the interpreter runs alone with that stored program, camera off
    alone = load_controller(path, program="left")
    assert alone.kind == KIND_MBN and alone.program == "left" and not alone.needs_camera
    _, a = _drive(alone, [0, 0])
    _, b = _drive(make_controller(mbn_spec.interpreter_spec, "left"), [0, 0])
    np.testing.assert_array_equal(a, b)


# --------------------------------------------------------------------------------------------
# The MBN controller
# --------------------------------------------------------------------------------------------


def test_mbn_sets_the_program_the_camera_selects(mbn_spec, interpreter_spec):
    """A program module without memory: camera 1 gives the right program, camera 2 the left;
    the MBN then drives exactly as the interpreter with that program."""
    mbn = make_controller(mbn_spec)
    for camera, name in ((1, "right"), (2, "left")):
        state, vw = _drive(mbn, [camera] * 3)
        rates = jax.nn.sigmoid(state.pm_y)
        np.testing.assert_allclose(rates[0], interpreter_spec.programs[name], atol=1e-12)
        _, fixed = _drive(
            _INTERPRETERS.setdefault(name, make_controller(interpreter_spec, name)), [0] * 3
        )
        np.testing.assert_allclose(vw, fixed, atol=1e-9)
    # nothing in view: the PM's inputs are 0, so the program is sigmoid(0) = 0.5
    state, _ = _drive(mbn, [0])
    np.testing.assert_allclose(jax.nn.sigmoid(state.pm_y), 0.5, atol=1e-12)
    # at the start every potential is 0
    start = mbn.initial_state(4)
    assert start.pm_y.shape == (4, K) and not np.any(start.pm_y)
    assert start.im_y.shape == (4, interpreter_spec.interpreter.num_neurons)
    assert not np.any(start.im_y)


def test_a_latching_program_module_remembers_the_last_tile(interpreter_spec):
    """Self-excited neurons with a bias of minus half the self-weight are bistable: the program
    of the last tile seen stays after the tile leaves the view, until the other kind is seen."""
    s = np.array([1.0, -1.0, 1.0])  # the pattern a one-colour tile switches on
    pm = make_ctrnn(
        np.diag([20.0, 20.0, 20.0]), np.stack([40 * s, -40 * s], -1), 0.2, bias=np.full(K, -10.0)
    )
    mbn = make_controller(MBNControllerSpec(interpreter_spec, pm, (2, 0, 1), pm_substeps=4))
    one = (s > 0).astype(float)
    pattern = lambda state: np.asarray(jax.nn.sigmoid(state.pm_y - 10.0))[0]  # noqa: E731
    state, _ = _drive(mbn, [1] * 10 + [0] * 30)
    np.testing.assert_allclose(pattern(state), one, atol=1e-3)
    state, _ = _drive(mbn, [1] * 10 + [0] * 10 + [2] * 10 + [0] * 30)
    np.testing.assert_allclose(pattern(state), 1 - one, atol=1e-3)


# --------------------------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------------------------


def _mutated(data, change):
    data = copy.deepcopy(data)
    change(data)
    return data


def _set(*keys_and_value):
    *keys, value = keys_and_value

    def change(data):
        target = data
        for k in keys[:-1]:
            target = target[k]
        if value is _DELETE:
            del target[keys[-1]]
        else:
            target[keys[-1]] = value

    return change


_DELETE = object()

CTRNN_CASES = [
    (_set("kind", _DELETE), r"not a controller file \(kind None, expected one of mbn.controller"),
    (_set("kind", "x"), r"not a controller file \(kind 'x', expected one of mbn.controller.ctrnn"),
    (_set("format_version", 2), r"format_version 2 is not supported"),
    (_set("format_version", _DELETE), r"missing field 'format_version'"),
    (_set("network", _DELETE), r"missing field 'network'"),
    (_set("network", "W", [[1.0, 2.0, 3.0], [1.0, 2.0, 3.0]]), r"network.W: must be square"),
    (_set("network", "WE", [[0.0, 0.0, 0.0]] * 2), r"network.WE: expected shape"),
    (_set("network", "WE", [[0.0] * 4] * 3), r"3 inputs I1..I3, but WE has 4 columns"),
    (_set("network", "tau", [0.5, -1.0, 0.5]), r"network.tau: time constants must be > 0"),
    (_set("sensors", "sonars", [*PAPER_SONARS, 16]), r"sensors: sonars must be Stage indices 0"),
    (_set("sensors", "sonars", [0, 1, 2]), r"must include the paper's 10 sonars"),
    (_set("sensors", "sonars", "all"), r"sensors.sonars: expected a list of integers"),
    (_set("motor", "speed_neuron", 3), r"motor.speed_neuron 3 is not one of the 3 neurons"),
    (_set("motor", "turn_neuron", _DELETE), r"motor: missing field 'turn_neuron'"),
    (_set("substeps", 0), r"substeps must be an integer in \[1, 10000\], got 0"),
    (_set("substeps", 10**9), r"substeps must be an integer in \[1, 10000\], got 1000000000"),
    (_set("dt", "fast"), r"dt: expected a finite number"),
    (_set("dt", 1e6), r"dt must be a number in \[0.001, 1\] s, got 1000000.0"),
    (_set("network", "W", [["1", 0, 0], [0, 0, 0], [0, 0, 0]]), r"network.W: expected numbers"),
    (_set("method", "leapfrog"), r"method must be euler or rk4"),
    (_set("behavior", "up"), r"behavior: unknown rule 'up'"),
    (_set("weights", []), r"unknown field\(s\) 'weights'"),
    (_set("metadata", [1, 2]), r"metadata must be an object"),
]


@pytest.mark.parametrize(("change", "message"), CTRNN_CASES)
def test_bad_ctrnn_files_give_one_line_naming_the_file(tmp_path, ctrnn_spec, change, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(_mutated(controller_to_dict(ctrnn_spec), change)))
    with pytest.raises(MbnInputError) as exc:
        load_controller(path)
    text = str(exc.value)
    assert text.startswith(f"{path}: ") and "\n" not in text
    assert re.search(message, text), text


INTERPRETER_CASES = [
    (_set("programs", "right", [0.5, 0.5]), r"programs.right: expected 3 values"),
    (_set("programs", "left", [0.5, 1.5, 0.5]), r"programs.left: values must be in \[0, 1\]"),
    (_set("programs", {}), r"an interpreter file needs at least one program"),
    (_set("interpreter", "connections", 0, "V[1,2]"), r"interpreter.connections: .*'V\[1,2\]'"),
    (_set("interpreter", "connections", 0, "W[1,7]"), r"W\[1,7\] is out of range"),
    (_set("interpreter", "num_original", 4), r"make 13 neurons, but W is 12x12"),
    (_set("interpreter", "mul_output", 3), r"mul_output 3 is not a neuron"),
    (_set("interpreter", "lower", [0.0]), r"interpreter.lower: expected 3 values"),
    (_set("interpreter", "lower", [100.0, 100.0, 100.0]), r"lower 100 must be < upper"),
    (_set("interpreter", "net", "WE", _DELETE), r"interpreter.net: missing field 'WE'"),
    (_set("motor", "turn_neuron", 5), r"turn_neuron 5 is not one of the 3 neurons of the interp"),
    (_set("sensors", "sonars", [*PAPER_SONARS, -1]), r"sonars must be Stage indices"),
]


@pytest.mark.parametrize(("change", "message"), INTERPRETER_CASES)
def test_bad_interpreter_files(tmp_path, interpreter_spec, change, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(_mutated(controller_to_dict(interpreter_spec), change)))
    with pytest.raises(MbnInputError) as exc:
        load_controller(path, program="right")
    text = str(exc.value)
    assert text.startswith(f"{path}: ") and "\n" not in text
    assert re.search(message, text), text


MBN_CASES = [
    (_set("program_module", "program_neurons", [0, 1]), r"the interpreter has 3 programmable"),
    (_set("program_module", "program_neurons", [0, 1, 3]), r"indices must be in 0..2"),
    (_set("program_module", "program_neurons", [0, 1, 1]), r"a neuron is listed twice"),
    (_set("program_module", "network", "WE", [[1.0] * 3] * 3), r"2 camera inputs"),
    (_set("program_module", "substeps", 0), r"program_module.substeps must be an integer >= 1"),
    (_set("program_module", _DELETE), r"missing field 'program_module'"),
    (_set("program_module", "camera", "range", -1.0), r"camera range must be in \(0, "),
    (_set("program_module", "camera", "zoom", 2.0), r"unknown field\(s\) 'zoom'"),
    (
        _set("program_module", "initial", {"rule": "up", "potentials": [0.0] * 3}),
        r"program_module.initial: unknown rule 'up'",
    ),
    (
        _set("program_module", "initial", {"rule": "right", "potentials": [0.0] * 2}),
        r"program_module.initial.potentials: the program module has 3 neurons, got 2",
    ),
    (
        _set("program_module", "initial", {"rule": "right", "potentials": [0.0, "a", 0.0]}),
        r"program_module.initial.potentials: expected",
    ),
    (
        _set("program_module", "initial", {"rule": "left", "potentials": [0.0] * 3, "x": 1}),
        r"program_module.initial: unknown field\(s\) 'x'",
    ),
    (
        _set(
            "program_module",
            "initial",
            {"rule": "right", "potentials": [0.0] * 3, "program": [0.9, 0.9, 0.9]},
        ),
        r"program_module.initial.program \[0.9, 0.9, 0.9\] is not what its potentials send",
    ),
]


def test_mbn_camera_is_kept_and_optional(tmp_path, mbn_spec):
    """The camera the program module was trained with travels in the file; older files without
    one get the default camera."""
    import dataclasses

    from mbn.world.engine import CameraConfig

    narrow = dataclasses.replace(mbn_spec, camera=CameraConfig(fov_deg=40.0, range=1.5))
    path = tmp_path / "mbn.json"
    save_controller(path, narrow)
    assert load_controller(path).camera == CameraConfig(fov_deg=40.0, range=1.5)
    data = json.loads(path.read_text())
    del data["program_module"]["camera"]
    path.write_text(json.dumps(data))
    assert load_controller(path).camera == CameraConfig()


@pytest.mark.parametrize(("change", "message"), MBN_CASES)
def test_bad_mbn_files(tmp_path, mbn_spec, change, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(_mutated(controller_to_dict(mbn_spec), change)))
    with pytest.raises(MbnInputError) as exc:
        load_controller(path)
    text = str(exc.value)
    assert text.startswith(f"{path}: ") and "\n" not in text
    assert re.search(message, text), text


def test_other_files_are_refused_clearly(tmp_path):
    mul = tmp_path / "mul.json"
    mul.write_text(json.dumps(multiplier_to_dict(load_default())))
    with pytest.raises(MbnInputError, match=r"mul.json: is a multiplier, not a controller"):
        load_controller(mul)
    listing = tmp_path / "list.json"
    listing.write_text("[1, 2]")
    with pytest.raises(MbnInputError, match=r"list.json: not a controller file \(a JSON list"):
        load_controller(listing)
    broken = tmp_path / "broken.json"
    broken.write_text('{"kind": "mbn.controller.ctrnn",\n "network": {')
    with pytest.raises(MbnInputError, match=r"broken.json:2: invalid JSON"):
        load_controller(broken)
    with pytest.raises(MbnInputError, match=r"missing.json: cannot read"):
        load_controller(tmp_path / "missing.json")


def test_choosing_programs(tmp_path, ctrnn_spec, interpreter_spec):
    with pytest.raises(MbnInputError, match="a plain CTRNN controller has no programs"):
        make_controller(ctrnn_spec, "right")
    with pytest.raises(MbnInputError, match=r"choose a program .*\(right, left\)"):
        make_controller(interpreter_spec)
    with pytest.raises(MbnInputError, match=r"no program 'up' \(the file has: right, left\)"):
        make_controller(interpreter_spec, "up")
    single = InterpreterControllerSpec(
        interpreter_spec.interpreter, {"right": interpreter_spec.programs["right"]}
    )
    assert make_controller(single).program == "right"


def test_specs_validate_when_built(interpreter_spec):
    net, _ = _nets()
    with pytest.raises(MbnInputError, match=r"motor\.speed_neuron 7"):
        CTRNNControllerSpec(net, motor=MotorMap(speed_neuron=7))
    with pytest.raises(MbnInputError, match="expected one network"):
        CTRNNControllerSpec(make_ctrnn(np.zeros((2, 3, 3)), np.zeros((2, 3, 3)), 1.0))
    with pytest.raises(MbnInputError, match=r"programs.right: values must be in \[0, 1\]"):
        InterpreterControllerSpec(interpreter_spec.interpreter, {"right": [0.1, -0.2, 0.3]})
    with pytest.raises(MbnInputError, match="2 camera inputs"):
        MBNControllerSpec(interpreter_spec, net, (0, 1, 2))


def test_a_failed_save_writes_nothing(tmp_path, ctrnn_spec, interpreter_spec):
    path = tmp_path / "c.json"
    path.write_text("precious\n")
    net = ctrnn_spec.net
    with pytest.raises(MbnInputError, match="cannot be written as JSON"):
        save_controller(path, CTRNNControllerSpec(net, metadata={"when": object()}))
    with pytest.raises(MbnInputError, match="at least one program"):
        save_controller(path, InterpreterControllerSpec(interpreter_spec.interpreter, {}))
    with pytest.raises(MbnInputError, match="not a controller spec"):
        save_controller(path, net)  # type: ignore[arg-type]
    with pytest.raises(MbnInputError, match="does not exist"):
        save_controller(tmp_path / "no" / "c.json", ctrnn_spec)
    assert path.read_text() == "precious\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.json"]


def test_a_weight_finite_in_json_but_too_large_for_float32_is_refused_by_name(tmp_path, ctrnn_spec):
    from mbn.precision import scope

    path = tmp_path / "big.json"
    data = controller_to_dict(ctrnn_spec)
    data["network"]["W"][0][0] = 1e39
    path.write_text(json.dumps(data))
    with scope("float32"), pytest.raises(MbnInputError) as exc:
        load_controller(path)
    assert "network.W: a value of magnitude 1e+39 is too large for float32" in str(exc.value)
    assert "NaN" not in str(exc.value) and str(path) in str(exc.value)


# --------------------------------------------------------------------------------------------
# The MBN's initial state (program_module.initial)
# --------------------------------------------------------------------------------------------


def _latch_pm(programs):
    """A program module with one bistable memory neuron (0: a one-colour tile switches it on, a
    two-colour tile off) and three output neurons that send the right program when it is on and
    the left program when it is off; at rest (potentials 0) it is off: the left program."""
    right, left = np.asarray(programs["right"]), np.asarray(programs["left"])
    logit = lambda p: np.log(p / (1 - p))  # noqa: E731
    W = np.zeros((K + 1, K + 1))
    W[0, 0] = 20.0
    W[1:, 0] = logit(right) - logit(left)
    WE = np.zeros((K + 1, 2))
    WE[0] = [40.0, -40.0]
    bias = np.concatenate([[-10.0], logit(left)])
    return make_ctrnn(W, WE, 0.2, bias=bias)


@pytest.fixture(scope="session")
def started_mbn(interpreter_spec):
    """An MBN whose PM starts in the state it latches after a one-colour tile (rule right), and
    the same MBN without ``initial`` (a file written before the field)."""
    from mbn.controllers import PMInitial
    from mbn.experiments.program_module import latch_after_tile

    pm = _latch_pm(interpreter_spec.programs)
    latch = latch_after_tile(pm, 1, (1, 2, 3))
    assert latch is not None
    np.testing.assert_allclose(latch.program, interpreter_spec.programs["right"], atol=1e-3)
    at_rest = MBNControllerSpec(interpreter_spec, pm, (1, 2, 3))
    import dataclasses

    started = dataclasses.replace(at_rest, initial=PMInitial("right", tuple(latch.potentials)))
    return started, at_rest


def test_mbn_initial_round_trip_and_files_without_it_start_at_rest(tmp_path, started_mbn):
    started, at_rest = started_mbn
    path = tmp_path / "mbn.json"
    save_controller(path, started)
    data = json.loads(path.read_text())
    initial = data["program_module"]["initial"]
    assert initial["rule"] == "right" and len(initial["potentials"]) == K + 1
    np.testing.assert_allclose(
        initial["program"], started.interpreter_spec.programs["right"], atol=1e-3
    )
    loaded = load_controller(path)
    assert loaded.initial_rule == "right"
    y = np.asarray(loaded.initial_state(2).pm_y)
    np.testing.assert_allclose(y, np.tile(started.initial.potentials, (2, 1)), rtol=1e-6)
    # the interpreter alone has no initial rule
    assert load_controller(path, program="left").initial_rule is None
    # an older file, without the field: potentials 0, no rule
    del data["program_module"]["initial"]
    path.write_text(json.dumps(data))
    old = load_controller(path)
    assert old.initial_rule is None and old.spec.initial is None
    assert np.all(np.asarray(old.initial_state(2).pm_y) == 0)
    save_controller(tmp_path / "again.json", at_rest)
    assert "initial" not in json.loads((tmp_path / "again.json").read_text())["program_module"]


@pytest.mark.slow
def test_an_mbn_started_as_rf_drives_as_the_interpreter_with_rfs_program_before_a_tile(
    started_mbn, interpreter_spec
):
    """Before its camera first sees a tile, the MBN started in its one-colour state sends the
    same motor commands as the interpreter with the right program; at rest it does not (its PM
    then sends the left program)."""
    from mbn.experiments.trials import TrialSpec, run_trials
    from mbn.world.engine import CameraConfig
    from mbn.world.mazes.builtin import builtin_maze

    started, at_rest = started_mbn
    maze = builtin_maze("fig4")
    spec = TrialSpec(behavior="tiles", seconds=12.0)

    def drive(loaded):
        _, result, _ = run_trials(
            maze,
            spec,
            loaded.controller,
            loaded.initial_state,
            dt=loaded.dt,
            sensors=loaded.sensors,
            camera=CameraConfig(range=0.8),  # the camera the reproduced MBNs read
            record_every=1,
        )
        t = result.trajectory
        return np.asarray(t.v), np.asarray(t.w), np.asarray(t.camera)

    v_im, w_im, _ = drive(make_controller(interpreter_spec, "right"))
    v, w, camera = drive(make_controller(started))
    v_rest, w_rest, camera_rest = drive(make_controller(at_rest))
    seen = np.where(camera.any(1), camera.argmax(1), camera.shape[1])  # first step with a tile
    before = np.arange(camera.shape[1])[None, :] < seen[:, None]
    assert before.sum() >= 900  # robot-steps before a tile is in view (of 10 x 120)
    motor = lambda a, b, c, d: np.maximum(np.abs(a - b), np.abs(c - d))[before]  # noqa: E731
    assert motor(v, v_im, w, w_im).max() <= 1e-3
    seen_rest = np.where(camera_rest.any(1), camera_rest.argmax(1), camera_rest.shape[1])
    before = np.arange(camera.shape[1])[None, :] < np.minimum(seen, seen_rest)[:, None]
    assert motor(v_rest, v_im, w_rest, w_im).max() > 0.05


# --------------------------------------------------------------------------------------------
# A CTRNN that reads the tiles itself (the monolithic contender, docs/contest.md)
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="session")
def tiles_spec():
    """A 4-neuron CTRNN with I1..I3 and three tile inputs; tile k drives neuron 1 (the turning
    neuron) by +/-: one-colour tiles turn it left, two-colour ones right, three-colour none."""
    from mbn.world.engine import CameraConfig

    rng = np.random.default_rng(4)
    WE = np.zeros((4, 6))
    WE[0, 0], WE[1, 1], WE[2, 2] = rng.uniform(-3, 3, 3)
    WE[1, 3], WE[1, 4] = 8.0, -8.0
    net = make_ctrnn(rng.uniform(-2, 2, (4, 4)), WE, 0.5, bias=rng.uniform(-1, 1, 4))
    return CTRNNControllerSpec(
        net,
        tile_rules=("right", "left", "straight-right"),
        camera=CameraConfig(range=0.8),
        metadata={"stage": "test"},
    )


def test_a_ctrnn_with_tile_rules_round_trips_and_reads_the_camera(tmp_path, tiles_spec):
    path = tmp_path / "mono.json"
    save_controller(path, tiles_spec)
    data = json.loads(path.read_text())
    assert data["kind"] == KIND_CTRNN
    assert data["tile_rules"] == ["right", "left", "straight-right"]
    assert data["camera"]["range"] == pytest.approx(0.8)
    loaded = load_controller(path)
    assert loaded.needs_camera and loaded.camera is not None and loaded.camera.range == 0.8
    assert loaded.tile_rules == ("right", "left", "straight-right")
    # it drives as the spec does, and the camera's reading moves its turning neuron
    _, original = _drive(make_controller(tiles_spec), [0, 1, 1])
    _, again = _drive(loaded, [0, 1, 1])
    np.testing.assert_array_equal(original, again)
    _, one = _drive(loaded, [1, 1, 1])
    _, two = _drive(loaded, [2, 2, 2])
    _, three = _drive(loaded, [3, 3, 3])
    assert np.all(one[-1, 1] > three[-1, 1]) and np.all(two[-1, 1] < three[-1, 1])
    # a follower's file has neither field: it reads and writes as before
    plain = controller_to_dict(CTRNNControllerSpec(tiles_spec.net.replace(WE=np.eye(4, 3))))
    assert "tile_rules" not in plain and "camera" not in plain


TILES_CASES = [
    (_set("tile_rules", _DELETE), r"tile_rules and camera go together"),
    (_set("tile_rules", ["right", "up", "left"]), r"tile_rules: unknown rule 'up'"),
    (_set("tile_rules", "right"), r"tile_rules: expected a list of rule names"),
    (_set("tile_rules", ["right", "left"]), r"3 inputs I1..I3 and 2 camera inputs .* 6 columns"),
    (_set("tile_rules", ["right"] * 7), r"one rule per tile kind \(1 to 6\), got 7"),
    (_set("camera", "range", -1.0), r"camera: camera range must be in \(0, 5.0\] m, got -1.0"),
]


@pytest.mark.parametrize(("change", "message"), TILES_CASES)
def test_bad_tile_reading_ctrnn_files(tmp_path, tiles_spec, change, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(_mutated(controller_to_dict(tiles_spec), change)))
    with pytest.raises(MbnInputError) as exc:
        load_controller(path)
    text = str(exc.value)
    assert text.startswith(f"{path}: ") and "\n" not in text
    assert re.search(message, text), text


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (["0.5", 0.5, 0.5], r"programs\.right: expected numbers, got text '0\.5' at index 0"),
        ([0.5, True, 0.5], r"programs\.right: expected numbers, got true at index 1"),
        ("0.5,0.5,0.5", r"programs\.right: expected a list of numbers, got text"),
        (np.array(["0.5"] * 3), r"programs\.right: expected numbers, got an array of <U3"),
    ],
)
def test_program_values_written_as_text_are_refused(interpreter_spec, value, message):
    """NumPy reads ``"0.5"`` as 0.5: a program written as text was run in silence."""
    with pytest.raises(MbnInputError, match=message):
        InterpreterControllerSpec(interpreter_spec.interpreter, {"right": value})
    with pytest.raises(MbnInputError, match=r"program_module\.readout: expected numbers, got"):
        MBNControllerSpec(
            interpreter_spec,
            make_ctrnn(np.zeros((3, 3)), np.zeros((3, 2)), 0.5),
            (0, 1),
            readout=[["1", 0.0], [0.0, 1.0], [0.0, 1.0]],
        )


def test_a_recorded_sha256_is_checked_on_reading(tmp_path, interpreter_spec, mbn_spec):
    """An interpreter or MBN file whose metadata records the sha256 of its interpreter's weights
    (as the runs write them) reads back in float32 and float64; with a weight changed since, or
    a recorded value that is no sha256, it is refused in one line naming the file."""
    import dataclasses

    digest = interpreter_spec.interpreter.digest()
    for name, spec in (("im", interpreter_spec), ("mbn", mbn_spec)):
        path = tmp_path / f"{name}.json"
        save_controller(path, dataclasses.replace(spec, metadata={"sha256": digest}))
        for x64 in (False, True):
            with jax.enable_x64(x64):
                assert load_controller(path, "right").spec.metadata["sha256"] == digest
        data = json.loads(path.read_text())
        data["interpreter"]["net"]["W"][0][1] += 1e-6
        changed = tmp_path / f"{name}_changed.json"
        changed.write_text(json.dumps(data))
        message = (
            re.escape(f"{changed}: the interpreter's sha256 is ")
            + "[0-9a-f]{12}"
            + re.escape(
                f"…, not the {digest[:12]}… its metadata records: its weights were changed since "
                "the file was written"
            )
            + "$"
        )
        with pytest.raises(MbnInputError, match=message):
            load_controller(changed, "right")
        data = json.loads(path.read_text())
        data["metadata"]["sha256"] = "abc"
        changed.write_text(json.dumps(data))
        with pytest.raises(MbnInputError, match=r"metadata\.sha256: expected the sha256 of"):
            load_controller(changed, "right")
    # a spec recording another interpreter's sha256 is not written
    with pytest.raises(MbnInputError, match="weights were changed"):
        save_controller(
            tmp_path / "other.json",
            dataclasses.replace(interpreter_spec, metadata={"sha256": "0" * 64}),
        )
    assert not (tmp_path / "other.json").exists()
