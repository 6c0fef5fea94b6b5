"""The switched controller kind (``mbn.controller.switched``): the MBN's two baselines, the
oracle that swaps the weights of one state (``swap``) and the gate among followers running side
by side (``gate``). Files, errors, and how they drive next to a plain CTRNN and to each other."""

from __future__ import annotations

import copy
import json
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.cli.main import main
from mbn.control.switched import NO_RULE
from mbn.controllers import (
    KIND_SWITCHED,
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    MBNControllerSpec,
    PMInitial,
    SwitchedControllerSpec,
    controller_to_dict,
    decoded_networks,
    load_controller,
    make_controller,
    read_controller_spec,
    save_controller,
    switched_from_mbn,
)
from mbn.controllers.builtin import SWITCHED_KIND
from mbn.errors import MbnInputError
from mbn.experiments.trials import TrialSpec, run_trials
from mbn.networks.ctrnn import make_ctrnn
from mbn.networks.multiplier import load_default
from mbn.networks.programmable import build_interpreter, differing_connections
from mbn.paper import published_lf, published_rf
from mbn.world.engine import CameraConfig
from mbn.world.mazes.builtin import crossroad
from mbn.world.rollout import Observation, map_controller
from mbn.world.sensors import NoiseConfig

#: The published followers are stable under RK4 at 10 ms steps (Euler would need 0.77 ms).
RUN = {"method": "rk4", "substeps": 10}
CAMERA = CameraConfig(range=0.8)


def _switched(mode="swap", initial="right", **changes):
    fields = {
        "networks": {"right": published_rf(), "left": published_lf()},
        "mode": mode,
        "tile_rules": ("right", "left"),
        "initial": initial,
        "camera": CAMERA,
        "metadata": {"note": "test"},
        **RUN,
    }
    return SwitchedControllerSpec(**{**fields, **changes})


# --------------------------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("mode", ["swap", "gate"])
def test_a_switched_file_round_trips(tmp_path, mode):
    spec = _switched(mode)
    path = tmp_path / "switched.json"
    save_controller(path, spec)
    data = json.loads(path.read_text())
    assert data["kind"] == KIND_SWITCHED and data["mode"] == mode
    assert list(data["networks"]) == ["right", "left"]
    assert data["tile_rules"] == ["right", "left"] and data["initial"] == "right"
    assert data["camera"] == {"fov_deg": CAMERA.fov_deg, "range": 0.8}
    again = read_controller_spec(path)
    assert isinstance(again, SwitchedControllerSpec) and again.mode == mode
    assert controller_to_dict(again) | {"provenance": None} == data | {"provenance": None}
    for rule, net in spec.networks.items():
        for name in ("W", "WE", "tau", "bias", "gain"):
            np.testing.assert_array_equal(getattr(again.networks[rule], name), getattr(net, name))
    loaded = load_controller(path)
    assert loaded.kind == KIND_SWITCHED and loaded.needs_camera and loaded.camera == CAMERA
    assert loaded.tile_rules == ("right", "left") and loaded.initial_rule == "right"
    assert loaded.programs == {} and loaded.program is None
    assert loaded.network_steps == 2 * RUN["substeps"]
    state = loaded.initial_state(3)
    assert np.asarray(state.y).shape == ((3, 3) if mode == "swap" else (3, 2, 3))
    assert np.asarray(state.rule).tolist() == [0, 0, 0]


def test_without_initial_no_rule_is_in_force_before_the_first_tile(tmp_path):
    path = tmp_path / "switched.json"
    save_controller(path, _switched(initial=None))
    data = json.loads(path.read_text())
    assert data["initial"] is None
    del data["initial"]  # the field may be left out
    path.write_text(json.dumps(data))
    loaded = load_controller(path)
    assert loaded.initial_rule is None and loaded.spec.initial is None
    assert np.asarray(loaded.initial_state(2).rule).tolist() == [NO_RULE] * 2


def test_rule_names_are_normalised_and_drawn():
    spec = _switched(networks={"Right": published_rf(), "left": published_lf()}, initial="right")
    assert spec.rules == ("right", "left") and spec.tile_networks == (0, 1)
    assert set(SWITCHED_KIND.weights(spec)) == {
        f"{rule} {name}" for rule in ("right", "left") for name in ("W", "WE", "bias")
    }


def _mutated(data, change):
    data = copy.deepcopy(data)
    change(data)
    return data


_DELETE = object()


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


def _four_neurons(data):
    net = make_ctrnn(np.zeros((4, 4)), np.zeros((4, 3)), 0.5)
    data["networks"]["left"] = net.to_dict()


def _extra_network(data):
    data["networks"]["straight-right"] = copy.deepcopy(data["networks"]["left"])


def _same_rule_twice(data):
    data["networks"]["RIGHT"] = copy.deepcopy(data["networks"]["right"])


BAD_FILES = [
    (_set("mode", "blend"), r"mode must be one of swap, gate, got 'blend'"),
    (_set("mode", 1), r"mode must be one of swap, gate, got 1"),
    (_set("weights", []), r"unknown field\(s\) 'weights'"),
    (_set("networks", "right", "scale", 2.0), r"networks.right: unknown field\(s\) 'scale'"),
    (_set("mode", _DELETE), r"missing field 'mode'"),
    (_set("camera", _DELETE), r"missing field 'camera'"),
    (_set("networks", {}), r"networks: expected an object of rule -> network, with one at least"),
    (_set("networks", []), r"networks: expected"),
    (_four_neurons, r"networks.left: 4 neurons, but networks.right has 3: the networks must all"),
    (
        _set("tile_rules", ["right", "left", "straight-right"]),
        r"tile_rules: no network for rule straight-right \(networks: right, left\)",
    ),
    (
        _extra_network,
        r"networks.straight-right: no tile puts straight-right in force \(tile_rules: right, "
        r"left\)",
    ),
    (_same_rule_twice, r"networks: 'right' and 'RIGHT' are the same rule \(right\), given twice"),
    (_set("networks", "up", {"W": [[0.0]], "WE": [[0, 0, 0]], "tau": [1.0]}), r"unknown rule 'up'"),
    (_set("networks", "left", "WE", [[0.0] * 4] * 3), r"networks.left: .* but WE has 4 columns"),
    (_set("networks", "left", "tau", [0.5, -1, 0.5]), r"networks.left.tau: time constants"),
    (_set("tile_rules", ["right", "up"]), r"tile_rules: unknown rule 'up'"),
    (_set("tile_rules", "right"), r"tile_rules: expected a list of rule names"),
    (
        _set("initial", "straight-left"),
        r"initial: straight-left is none of the tile rules \(right, left\)",
    ),
    (_set("initial", "up"), r"initial: unknown rule 'up'"),
    (_set("initial", 1), r"initial: expected a rule name or null, got 1"),
    (_set("motor", "speed_neuron", 3), r"motor.speed_neuron 3 is not one of the 3 neurons"),
    (_set("camera", "range", -1.0), r"camera: camera range must be in"),
    (_set("substeps", 0), r"substeps must be an integer in \[1, 10000\], got 0"),
    (_set("method", "leapfrog"), r"method must be euler or rk4"),
]


@pytest.mark.parametrize(("change", "message"), BAD_FILES)
def test_bad_switched_files_give_one_line_naming_the_file(tmp_path, change, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(_mutated(controller_to_dict(_switched()), change)))
    with pytest.raises(MbnInputError) as exc:
        load_controller(path)
    text = str(exc.value)
    assert text.startswith(f"{path}: ") and "\n" not in text
    assert re.search(message, text), text


def test_a_program_and_an_unstable_step_are_refused():
    with pytest.raises(MbnInputError, match=r"a switched controller has no programs"):
        make_controller(_switched(), "right")
    euler = _switched(method="euler", substeps=20)
    with pytest.raises(
        MbnInputError, match=r"^controller: networks.right: its network's step 5 ms"
    ):
        make_controller(euler)
    assert make_controller(euler, check_stability=False).kind == KIND_SWITCHED


# --------------------------------------------------------------------------------------------
# The camera latches the rule as the program module reads it
# --------------------------------------------------------------------------------------------


def _obs(n, camera, key=None):
    rng = np.random.default_rng(1)
    return Observation(
        ranges=jnp.asarray(rng.uniform(0.2, 3, (n, 10))),
        S=jnp.asarray(rng.uniform(0, 1, (n, 10))),
        inputs=jnp.asarray(rng.uniform(0, 1, (n, 3))),
        camera=jnp.full((n,), camera, jnp.int32),
        blobs=jnp.zeros((n,), jnp.int32),
        tile=jnp.zeros((n,), jnp.int32),
        stalled=jnp.zeros((n,), bool),
        t=jnp.zeros((n,)),
        key=key,
    )


def _steps(loaded, cameras, n=2, keys=None):
    """The states and (v, w) of ``n`` robots over steps with the given camera readings."""
    state = loaded.initial_state(n)
    step = jax.jit(map_controller(loaded.controller, state))
    states, out = [], []
    for t, c in enumerate(cameras):
        state, (v, w) = step(state, _obs(n, c, None if keys is None else keys[t]))
        states.append(state)
        out.append((np.asarray(v), np.asarray(w)))
    return states, np.array(out)


@pytest.mark.parametrize("mode", ["swap", pytest.param("gate", marks=pytest.mark.slow)])
def test_the_rule_is_the_last_tile_in_view_of_the_kinds_it_knows(mode):
    """A tile of k colours in view puts tile_rules[k - 1] in force until another is seen; a tile
    of more colours than it has rules is not read (as the program module has no input for it)."""
    loaded = make_controller(_switched(mode, initial=None))
    cameras = [0, 1, 0, 3, 2, 2, 0, 3, 1, 0]
    states, _ = _steps(loaded, cameras)
    rules = [np.asarray(s.rule).tolist() for s in states]
    expected = [NO_RULE, 0, 0, 0, 1, 1, 1, 1, 0, 0]
    assert rules == [[r, r] for r in expected]


def test_swap_keeps_the_potentials_and_swaps_the_weights():
    """After a swap the state integrates under the other network from the potentials it had."""
    swap = make_controller(_switched("swap"))
    right = make_controller(CTRNNControllerSpec(published_rf(), **RUN))
    left = make_controller(CTRNNControllerSpec(published_lf(), **RUN))
    states, vw = _steps(swap, [0, 0, 0, 2, 2])
    rs, vw_right = _steps(right, [0, 0, 0])
    np.testing.assert_array_equal(vw[:3], vw_right)
    np.testing.assert_array_equal(np.asarray(states[2].y), np.asarray(rs[-1].y))
    # left from the potentials right left it at
    from_there = left.initial_state(2)._replace(y=states[2].y)
    step = jax.jit(map_controller(left.controller, from_there))
    state = from_there
    for _ in range(2):
        state, (v, w) = step(state, _obs(2, 2))
    np.testing.assert_allclose(np.asarray(states[-1].y), np.asarray(state.y), rtol=0, atol=1e-12)
    np.testing.assert_allclose(vw[-1], np.array([v, w]), rtol=0, atol=1e-12)


@pytest.mark.slow
def test_neuron_noise_is_the_ctrnns_for_one_network_and_each_gate_networks_own():
    noise = NoiseConfig(neuron_std=0.5)
    keys = [jax.random.split(jax.random.fold_in(jax.random.key(3), t), 2) for t in range(4)]
    plain = make_controller(CTRNNControllerSpec(published_rf(), **RUN), noise=noise)
    one = {"networks": {"right": published_rf()}, "tile_rules": ("right",)}
    _, vw_plain = _steps(plain, [0, 1, 1, 0], keys=keys)
    for mode in ("swap", "gate"):
        switched = make_controller(_switched(mode, **one), noise=noise)
        _, vw = _steps(switched, [0, 1, 1, 0], keys=keys)
        np.testing.assert_allclose(vw, vw_plain, rtol=0, atol=1e-12)
    # two copies of one network in a gate draw their own noise
    twins = _switched("gate", networks={"right": published_rf(), "left": published_rf()})
    states, _ = _steps(make_controller(twins, noise=noise), [0, 0], keys=keys)
    y = np.asarray(states[-1].y)
    assert np.abs(y[:, 0] - y[:, 1]).max() > 1e-3


# --------------------------------------------------------------------------------------------
# In a maze: the same as a plain CTRNN with one rule; swap and gate part at the switch
# --------------------------------------------------------------------------------------------

SECONDS = 8.0


def _drive(spec, maze, behavior="tiles"):
    loaded = make_controller(spec)
    _, result, _ = run_trials(
        maze,
        TrialSpec(behavior=behavior, seconds=SECONDS, repeats=2),
        loaded.controller,
        loaded.initial_state,
        dt=loaded.dt,
        sensors=loaded.sensors,
        camera=CAMERA,
        record_every=1,
        record_controller=True,
    )
    return result


@pytest.fixture(scope="module")
def tile_two():
    """Two robots entering a T whose south arm has a two-colour tile (left), starting as RF.
    The tests that drive them are slow tests: CI checks the latching step by step (above) and
    the one-rule drive; the contests drive the switched controllers in mazes."""
    maze = crossroad("LR", tile=2)
    return {mode: _drive(_switched(mode), maze) for mode in ("swap", "gate")}


@pytest.mark.parametrize("mode", ["swap", pytest.param("gate", marks=pytest.mark.slow)])
def test_with_one_rule_it_drives_as_the_plain_ctrnn(mode):
    maze = crossroad("LR", tile=1)
    plain = _drive(CTRNNControllerSpec(published_rf(), **RUN), maze)
    one = {"networks": {"right": published_rf()}, "tile_rules": ("right",)}
    switched = _drive(_switched(mode, **one), maze)
    a, b = plain.trajectory, switched.trajectory
    assert np.asarray(a.camera).max() == 1  # the tile was seen: the rule latched (to itself)
    for name in ("pose", "v", "w"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=0, atol=1e-9)
    assert np.asarray(switched.controller_state.rule).tolist() == [0, 0]


@pytest.mark.slow
def test_the_latched_rule_follows_the_camera_in_the_maze(tile_two):
    for result in tile_two.values():
        t = result.trajectory
        camera, rule = np.asarray(t.camera), np.asarray(t.controller.rule)
        final = np.asarray(result.controller_state.rule)
        after = np.concatenate([rule[:, 1:], final[:, None]], axis=1)  # the state after each step
        expected = np.where(camera == 2, 1, np.where(camera == 1, 0, rule))
        np.testing.assert_array_equal(after, expected)
        assert (rule[:, 0] == 0).all() and (final == 1).all()
        # the tile in force for the judge is the one the camera had latched
        tile = np.asarray(t.tile)
        assert (after[tile == 2] == 1).all()


@pytest.mark.slow
def test_swap_and_gate_part_only_after_the_switch(tile_two):
    swap, gate = tile_two["swap"].trajectory, tile_two["gate"].trajectory
    rule = np.asarray(swap.controller.rule)
    np.testing.assert_array_equal(rule, np.asarray(gate.controller.rule))
    camera = np.asarray(swap.camera)
    for robot in range(camera.shape[0]):
        switch = int(np.argmax(camera[robot] == 2))  # the first step with the tile in view
        assert 0 < switch < camera.shape[1] - 10
        for name in ("pose", "v", "w"):
            before = np.asarray(getattr(swap, name))[robot, :switch]
            np.testing.assert_array_equal(before, np.asarray(getattr(gate, name))[robot, :switch])
        gap = np.abs(np.asarray(swap.w)[robot, switch:] - np.asarray(gate.w)[robot, switch:])
        assert gap.max() > 1e-3


# --------------------------------------------------------------------------------------------
# From an MBN: the decoded networks of its programs; and `mbn evaluate --behavior tiles`
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def mbn_spec():
    rf, lf = published_rf(), published_lf()
    interp = build_interpreter(rf, differing_connections(rf, lf), load_default())
    programs = {
        "right": np.asarray(interp.program_of(rf)).tolist(),
        "left": np.asarray(interp.program_of(lf)).tolist(),
    }
    im = InterpreterControllerSpec(interp, programs, substeps=40, method="rk4")
    pm = make_ctrnn(np.zeros((3, 3)), np.zeros((3, 2)), 0.5)
    return MBNControllerSpec(
        im, pm, (0, 1, 2), camera=CAMERA, initial=PMInitial("left", (0.0, 0.0, 0.0))
    )


def test_the_decoded_networks_are_the_followers_the_programs_encode(mbn_spec):
    nets = decoded_networks(mbn_spec)
    assert list(nets) == ["right", "left"]
    for rule, original in (("right", published_rf()), ("left", published_lf())):
        for name in ("W", "WE", "tau", "bias", "gain"):
            np.testing.assert_allclose(
                getattr(nets[rule], name), getattr(original, name), rtol=1e-12, atol=1e-9
            )
    oracle = switched_from_mbn(mbn_spec, "gate")
    assert oracle.mode == "gate" and oracle.rules == ("right", "left")
    assert oracle.initial == "left" and oracle.camera == CAMERA
    assert (oracle.dt, oracle.substeps, oracle.method) == (0.1, 40, "rk4")
    assert switched_from_mbn(mbn_spec, substeps=10).substeps == 10
    unnamed = InterpreterControllerSpec(mbn_spec.interpreter_spec.interpreter, {"a": [0.5] * 3})
    pm = mbn_spec.program_module
    with pytest.raises(MbnInputError, match=r"the MBN has no program named right"):
        switched_from_mbn(MBNControllerSpec(unnamed, pm, (0, 1, 2)))


@pytest.mark.slow
def test_mbn_evaluate_takes_it_on_tiles(tmp_path, capsys):
    path = tmp_path / "oracle.json"
    save_controller(path, _switched("swap", initial="left"))
    args = ["--controller", path, "--maze", "fig4", "--behavior", "tiles", "--seconds", "2"]
    status = main(["evaluate", *map(str, args), "--json"])
    out, err = capsys.readouterr()
    assert status == 0, err
    result = json.loads(out)
    assert result["trials"] == 10 and result["seconds"] == 2.0
    status = main(["evaluate", *map(str, args)])
    out, err = capsys.readouterr()
    assert status == 0, err
    assert f"{KIND_SWITCHED}" in out and "behavior tiles (initial left)" in out
    status = main(["evaluate", *map(str, args), "--program", "right"])
    out, err = capsys.readouterr()
    assert status == 2 and "a switched controller has no programs" in err
