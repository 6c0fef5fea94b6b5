"""Controller kinds (``mbn.controllers.kinds``): a kind defined here, outside ``src/mbn``, is
saved, loaded, evaluated by ``mbn evaluate``, drawn and evolved through ``mbn``'s own paths; the
recipe of ``docs/architecture.md`` ("Adding a controller kind") runs as written; ``mbn``'s three
kinds are the registry's."""

from __future__ import annotations

import json
import re
import sys
import types
from dataclasses import dataclass, field, replace
from importlib.metadata import EntryPoint
from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.cli.main import main
from mbn.controllers import (
    KINDS,
    ControllerKind,
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    MBNControllerSpec,
    Runner,
    builtin,
    check_body,
    controller_kind,
    controller_to_dict,
    kind_of,
    load_controller,
    make_controller,
    read_controller_spec,
    register_controller_kind,
    registered_kinds,
    save_controller,
    unregister_controller_kind,
)
from mbn.controllers import kinds as kinds_module
from mbn.errors import MbnInputError
from mbn.evolution.de import DEConfig
from mbn.experiments.crossroads import CrossroadTask
from mbn.experiments.evolve import generation, kind_fitness, start
from mbn.networks.ctrnn import make_ctrnn
from mbn.networks.multiplier import load_default
from mbn.networks.programmable import build_interpreter, differing_connections
from mbn.paper import published_lf, published_rf
from mbn.viz.controllers import draw_controller, save_controller_png
from mbn.world.rollout import Shared
from mbn.world.sensors import SensorConfig

ARCHITECTURE = Path(__file__).parents[2] / "docs" / "architecture.md"

# --------------------------------------------------------------------------------------------
# A kind of controller kept outside mbn: a Braitenberg vehicle, and one that draws nothing
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BraitenbergSpec:
    """``v = 0.5 sigma(a)``, ``w = 2 sigma(b) - 1`` for ``(a, b) = weights @ [I1, I2, I3, 1]``
    (the motor mapping of mbn's CTRNN controllers, so that one drives as the other)."""

    weights: tuple[tuple[float, ...], ...]
    dt: float = 0.1
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        w = np.asarray(self.weights, np.float64)
        if w.shape != (2, 4) or not np.all(np.isfinite(w)):
            raise MbnInputError(f"weights: expected 2 x 4 finite numbers, got shape {w.shape}")
        object.__setattr__(self, "weights", tuple(map(tuple, w.tolist())))


class BraitenbergState(NamedTuple):
    weights: Any  # Shared: one (2, 4) matrix for every robot of a batch


def braitenberg_control(state: BraitenbergState, obs: Any) -> tuple[BraitenbergState, Any]:
    a, b = state.weights[:, :3] @ obs.inputs + state.weights[:, 3]
    return state, (0.5 * jax.nn.sigmoid(a), 1.0 * (2.0 * jax.nn.sigmoid(b) - 1.0))


class BraitenbergKind(ControllerKind):
    name = "tests.controller.braitenberg"
    spec_type = BraitenbergSpec

    def to_dict(self, spec: Any) -> dict[str, Any]:
        return {
            "weights": [list(r) for r in spec.weights],
            "dt": spec.dt,
            "metadata": dict(spec.metadata),
        }

    def from_dict(self, data: dict[str, Any], where: str) -> Any:
        check_body(data, where, ["weights", "dt"], ["metadata"])
        try:
            return BraitenbergSpec(data["weights"], data["dt"], data.get("metadata", {}))
        except (MbnInputError, TypeError, ValueError) as exc:
            raise MbnInputError(f"{where}: {exc}") from None

    def runner(self, spec: Any, program: str | None, noise: Any, where: str) -> Runner:
        if program is not None:
            raise MbnInputError(f"{where}: a Braitenberg vehicle has no programs")
        weights = jnp.asarray(spec.weights)

        def initial(n: int) -> BraitenbergState:
            return BraitenbergState(Shared(weights))

        return Runner(braitenberg_control, initial, sensors=SensorConfig(), dt=spec.dt)

    def weights(self, spec: Any) -> dict[str, np.ndarray]:
        return {"weights": np.asarray(spec.weights)}

    def genes(self, spec: Any) -> np.ndarray:
        return np.ravel(spec.weights)

    def with_genes(self, spec: Any, genes: np.ndarray) -> Any:
        return replace(spec, weights=np.reshape(genes, (2, 4)))


@dataclass(frozen=True)
class CruiseSpec:
    """Straight ahead at ``speed`` m/s: a kind that is neither drawn nor evolved."""

    speed: float = 0.3


def cruise_control(state: Any, obs: Any) -> tuple[Any, Any]:
    return state, (state.speed, jnp.zeros_like(state.speed))


class CruiseState(NamedTuple):
    speed: Any  # (B,)


class CruiseKind(ControllerKind):
    name = "tests.controller.cruise"
    spec_type = CruiseSpec

    def to_dict(self, spec: Any) -> dict[str, Any]:
        return {"speed": spec.speed}

    def from_dict(self, data: dict[str, Any], where: str) -> Any:
        check_body(data, where, ["speed"])
        return CruiseSpec(data["speed"])

    def runner(self, spec: Any, program: str | None, noise: Any, where: str) -> Runner:
        def initial(n: int) -> CruiseState:
            return CruiseState(jnp.full((n,), spec.speed))

        return Runner(cruise_control, initial, sensors=SensorConfig(), dt=0.1)


#: For the entry point test: a kind an installed package would name (not registered here).
BRAITENBERG = BraitenbergKind()

#: Drives straight ahead: a = 3, b = 0 (the built-in CTRNN of the same commands: ``_straight``).
STRAIGHT = BraitenbergSpec(((0.0, 0.0, 0.0, 3.0), (0.0, 0.0, 0.0, 0.0)), metadata={"lab": "t"})


def _straight_ctrnn() -> CTRNNControllerSpec:
    """The CTRNN of ``tests/cli/test_evaluate.py`` that drives straight ahead: no weights, the
    speed neuron biased on; its potentials stay 0, so it sends ``(0.5 sigma(3), 0)`` as
    :data:`STRAIGHT` does."""
    net = make_ctrnn(np.zeros((3, 3)), np.zeros((3, 3)), 0.5, bias=[0.0, 0.0, 3.0])
    return CTRNNControllerSpec(net, behavior="right")


@pytest.fixture
def registered():
    """The two kinds registered for one test, and taken out again."""
    added = []
    try:
        added.append(register_controller_kind(BraitenbergKind()))
        added.append(register_controller_kind(CruiseKind()))
        yield added
    finally:
        for kind in added:
            unregister_controller_kind(kind.name)


def _evaluate(capsys, path: Path, *extra: str) -> tuple[int, str, str]:
    status = main(
        ["evaluate", "--controller", str(path), "--maze", "fig4", "--behavior", "right", *extra]
    )
    captured = capsys.readouterr()
    return status, captured.out, captured.err


# --------------------------------------------------------------------------------------------
# mbn's own kinds go through the registry
# --------------------------------------------------------------------------------------------


def _builtin_specs() -> list[Any]:
    rf, lf = published_rf(), published_lf()
    interp = build_interpreter(rf, differing_connections(rf, lf), load_default())
    programs = {
        "right": np.asarray(interp.program_of(rf)).tolist(),
        "left": np.asarray(interp.program_of(lf)).tolist(),
    }
    im = InterpreterControllerSpec(interp, programs)
    pm = make_ctrnn(np.zeros((3, 3)), np.zeros((3, 2)), 0.5)
    return [CTRNNControllerSpec(rf), im, MBNControllerSpec(im, pm, (0, 1, 2))]


def test_mbns_three_kinds_are_registered_first_and_stay():
    assert tuple(registered_kinds())[:3] == KINDS
    for spec, kind in zip(
        _builtin_specs(),
        (builtin.CTRNN_KIND, builtin.INTERPRETER_KIND, builtin.MBN_KIND),
        strict=True,
    ):
        assert kind_of(spec) is kind and controller_kind(spec.kind) is kind
        assert controller_to_dict(spec)["kind"] == kind.name == spec.kind
        program = None if kind is builtin.CTRNN_KIND else "right"
        assert make_controller(spec, program, check_stability=False).kind == kind.name
        with pytest.raises(MbnInputError, match="is mbn's own"):
            unregister_controller_kind(kind.name)


def test_the_built_in_genomes_give_their_spec_back():
    rf_spec, im, _ = _builtin_specs()
    genes = builtin.CTRNN_KIND.genes(rf_spec)
    assert genes.shape == (9 + 9 + 3,)
    again = builtin.CTRNN_KIND.with_genes(rf_spec, genes)
    for name in ("W", "WE", "tau", "bias", "gain"):
        np.testing.assert_array_equal(getattr(again.net, name), getattr(rf_spec.net, name))
    assert (again.dt, again.substeps, again.motor) == (rf_spec.dt, rf_spec.substeps, rf_spec.motor)
    moved = builtin.CTRNN_KIND.with_genes(rf_spec, genes + 1.0)
    np.testing.assert_allclose(np.asarray(moved.net.bias), np.asarray(rf_spec.net.bias) + 1.0)
    program = builtin.INTERPRETER_KIND.genes(im)
    np.testing.assert_array_equal(program, im.programs["right"])
    evolved = builtin.INTERPRETER_KIND.with_genes(im, np.array([0.25, 2.0, -1.0]))
    assert evolved.programs == {"evolved": (0.25, 1.0, 0.0)}
    with pytest.raises(MbnInputError, match=r"mbn\.controller\.mbn cannot be evolved"):
        builtin.MBN_KIND.genes(_builtin_specs()[2])


# --------------------------------------------------------------------------------------------
# A kind from outside: saved and loaded
# --------------------------------------------------------------------------------------------


def test_a_kind_from_outside_is_saved_with_the_header_and_loaded_back(tmp_path, registered):
    path = tmp_path / "vehicle.json"
    save_controller(path, STRAIGHT)
    data = json.loads(path.read_text())
    assert list(data) == [
        "kind",
        "format_version",
        "mbn_version",
        "provenance",
        "weights",
        "dt",
        "metadata",
    ]
    assert data["kind"] == "tests.controller.braitenberg" and data["format_version"] == 1
    assert data["weights"] == [[0.0, 0.0, 0.0, 3.0], [0.0, 0.0, 0.0, 0.0]]
    assert read_controller_spec(path) == STRAIGHT
    loaded = load_controller(path)
    assert loaded.kind == "tests.controller.braitenberg" and loaded.spec == STRAIGHT
    assert loaded.dt == 0.1 and loaded.camera is None and loaded.network_steps == 1


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d.pop("weights"), r"missing field 'weights'"),
        (lambda d: d.update(wheels=2), r"unknown field\(s\) 'wheels'"),
        (lambda d: d.update(weights=[[1, 2]]), r"weights: expected 2 x 4 finite numbers"),
        (lambda d: d.update(format_version=2), r"format_version 2 is not supported"),
        (lambda d: d.update(kind="tests.controller.nothing"), r"expected one of .*braitenberg"),
    ],
)
def test_a_bad_file_of_the_kind_is_one_line_naming_it(tmp_path, registered, change, message):
    path = tmp_path / "bad.json"
    data = controller_to_dict(STRAIGHT)
    change(data)
    path.write_text(json.dumps(data))
    with pytest.raises(MbnInputError) as exc:
        load_controller(path)
    text = str(exc.value)
    assert text.startswith(f"{path}: ") and "\n" not in text
    assert re.search(message, text), text


def test_once_unregistered_its_files_are_refused(tmp_path):
    path = tmp_path / "vehicle.json"
    kind = register_controller_kind(BraitenbergKind())
    try:
        save_controller(path, STRAIGHT)
    finally:
        unregister_controller_kind(kind.name)
    with pytest.raises(MbnInputError, match=r"not a controller file \(kind 'tests\.controller"):
        load_controller(path)
    with pytest.raises(MbnInputError, match="not a controller spec: BraitenbergSpec"):
        save_controller(tmp_path / "again.json", STRAIGHT)


def test_registration_refuses_what_would_be_ambiguous(registered):
    class Named(BraitenbergKind):
        pass

    with pytest.raises(MbnInputError, match="registered already"):
        register_controller_kind(BraitenbergKind())
    for name in ("Braitenberg", "braitenberg", "my lab.x", ""):
        kind = Named()
        kind.name = name
        with pytest.raises(MbnInputError, match="lower-case words joined by dots"):
            register_controller_kind(kind)
    mine = Named()
    mine.name = "mbn.controller.mine"
    with pytest.raises(MbnInputError, match=r"names under 'mbn\.' are mbn's own"):
        register_controller_kind(mine)

    @dataclass(frozen=True)
    class Sub(BraitenbergSpec):
        pass

    other = Named()
    other.name, other.spec_type = "tests.controller.other", Sub
    with pytest.raises(
        MbnInputError, match=r"would be taken for those of tests\.controller\.brait"
    ):
        register_controller_kind(other)
    with pytest.raises(MbnInputError, match="must be a ControllerKind"):
        register_controller_kind(object())  # type: ignore[arg-type]
    with pytest.raises(MbnInputError, match="is not registered"):
        unregister_controller_kind("tests.controller.never")


def test_fields_that_would_overwrite_the_header_are_refused(tmp_path):
    class Sneaky(BraitenbergKind):
        name = "tests.controller.sneaky"

        def to_dict(self, spec: Any) -> dict[str, Any]:
            return {**super().to_dict(spec), "format_version": 7}

    kind = register_controller_kind(Sneaky())
    try:
        with pytest.raises(MbnInputError, match="may not include the header's"):
            save_controller(tmp_path / "s.json", STRAIGHT)
    finally:
        unregister_controller_kind(kind.name)
    assert not (tmp_path / "s.json").exists()


def test_an_installed_packages_entry_point_registers_its_kind(tmp_path, monkeypatch):
    path = tmp_path / "vehicle.json"
    kind = register_controller_kind(BraitenbergKind())
    try:
        save_controller(path, STRAIGHT)
    finally:
        unregister_controller_kind(kind.name)
    point = EntryPoint(
        "tests.controller.braitenberg",
        f"{__name__}:BRAITENBERG",
        kinds_module.ENTRY_POINT_GROUP,
    )
    monkeypatch.setattr(kinds_module, "_PLUGINS_READ", False)
    monkeypatch.setattr(
        "importlib.metadata.entry_points",
        lambda group: [point] if group == point.group else [],
    )
    try:
        assert read_controller_spec(path) == STRAIGHT
        assert controller_kind("tests.controller.braitenberg") is BRAITENBERG
    finally:
        unregister_controller_kind("tests.controller.braitenberg")


# --------------------------------------------------------------------------------------------
# evaluated, drawn, evolved
# --------------------------------------------------------------------------------------------


# slow: a second path; CI runs the recipe, which evaluates a kind of its own with mbn evaluate
@pytest.mark.slow
def test_mbn_evaluate_runs_the_kind_as_the_ctrnn_that_sends_the_same_commands(
    tmp_path, registered, capsys
):
    vehicle, ctrnn = tmp_path / "vehicle.json", tmp_path / "ctrnn.json"
    save_controller(vehicle, STRAIGHT)
    save_controller(ctrnn, _straight_ctrnn())
    args = ("--seconds", "10", "--repeats", "2", "--json")
    status, out, err = _evaluate(capsys, vehicle, *args)
    assert status == 0, err
    status, same, err = _evaluate(capsys, ctrnn, *args)
    assert status == 0, err
    result = json.loads(out)
    assert result["trials"] == 10 * 2 and result["junctions"] > 0
    assert json.loads(same) == result  # the same commands: the same trials, to the bit
    turning = replace(STRAIGHT, weights=((0.0, 0.0, 0.0, 3.0), (0.0, 0.0, 0.0, 1.5)))
    save_controller(vehicle, turning)
    status, out, err = _evaluate(capsys, vehicle, *args)
    assert status == 0, err
    assert json.loads(out) != result  # its own weights drive it
    status, out, err = _evaluate(capsys, vehicle, "--seconds", "5")
    assert status == 0, err
    assert f"{vehicle} (tests.controller.braitenberg) in maze 'fig4'" in out


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--program", "right"], "a Braitenberg vehicle has no programs"),
        (["--behavior", "tiles"], "needs a controller that reads the tiles"),
    ],
)
def test_mbn_evaluate_refuses_what_the_kind_cannot_do(tmp_path, registered, capsys, extra, message):
    vehicle = tmp_path / "vehicle.json"
    save_controller(vehicle, STRAIGHT)
    status, _, err = _evaluate(capsys, vehicle, "--seconds", "5", *extra)
    assert status == 2
    assert len(err.strip().splitlines()) == 1 and message in err, err


def test_a_kind_is_drawn_by_its_weights_and_one_without_as_text(tmp_path, registered):
    fig = draw_controller(STRAIGHT)
    titles = [ax.get_title() for ax in fig.axes]
    assert "weights 2x4" in titles
    cells = {t.get_text() for ax in fig.axes for t in ax.texts}
    assert {"3", "0"} <= cells  # the values, written in their cells
    text = draw_controller(CruiseSpec(0.25))
    lines = "\n".join(t.get_text() for ax in text.axes for t in ax.texts)
    assert "kind: tests.controller.cruise" in lines and "speed: 0.25" in lines
    assert any("no picture of its own" in ax.get_title() for ax in text.axes)
    save_controller_png(STRAIGHT, tmp_path / "vehicle.png")
    assert (tmp_path / "vehicle.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(MbnInputError, match="not a controller spec of a registered kind"):
        draw_controller(object())


def test_a_kind_without_a_drawing_or_genes_still_runs(tmp_path, registered, capsys):
    path = tmp_path / "cruise.json"
    save_controller(path, CruiseSpec(0.3))
    status, out, err = _evaluate(capsys, path, "--seconds", "5", "--json")
    assert status == 0, err
    assert json.loads(out)["trials"] == 10  # fig4's ten start marks
    with pytest.raises(MbnInputError, match=r"tests\.controller\.cruise cannot be evolved"):
        kind_fitness(CruiseSpec(0.3), CrossroadTask(variants=1, seconds=2))


# slow: a second path; CI runs the recipe, which evolves a kind of its own two generations
@pytest.mark.slow
def test_the_kind_is_evolved_by_de_its_population_in_one_batch(tmp_path, registered):
    task = CrossroadTask(rule="right", variants=1, seconds=5)
    fitness = kind_fitness(STRAIGHT, task)
    assert fitness.size == 8
    config = DEConfig(num_dims=8, popsize=4, init_low=-4.0, init_high=4.0, maximize=True)
    key = jax.random.key(3)
    state = start(key, config, fitness)
    first = float(state.best_fitness)
    for g in (1, 2):
        state = generation(key, g, state, config, fitness)
    assert int(state.generation) == 2 and float(state.best_fitness) >= first
    values = np.asarray(state.fitness)
    assert len(set(values.tolist())) > 1  # each genome drives as its own weights say
    # each genome of the batch scores as it does alone: the states were joined, not mixed
    alone = [float(fitness(np.asarray(state.population)[i : i + 1])[0]) for i in range(2)]
    np.testing.assert_allclose(alone, values[:2], rtol=1e-5, atol=1e-5)
    best = fitness.spec(state.best_genome)
    assert isinstance(best, BraitenbergSpec)
    np.testing.assert_allclose(np.ravel(best.weights), np.asarray(state.best_genome), rtol=1e-6)
    save_controller(tmp_path / "best.json", best)
    assert read_controller_spec(tmp_path / "best.json") == best
    with pytest.raises(MbnInputError, match=r"robot step dt 0\.05 s is not the task's 0\.1 s"):
        kind_fitness(replace(STRAIGHT, dt=0.05), task)


# --------------------------------------------------------------------------------------------
# the recipe of docs/architecture.md, run as written
# --------------------------------------------------------------------------------------------


def _recipe() -> list[str]:
    """The Python blocks of the section "Adding a controller kind", which must follow "Your own
    experiment"."""
    text = ARCHITECTURE.read_text()
    own = text.index("\n### Your own experiment\n")
    start_at = text.index("\n### Adding a controller kind\n")
    assert own < start_at
    end = re.compile(r"^#{2,3} ", re.M).search(text, start_at + 5)
    section = text[start_at : end.start() if end else len(text)]
    return re.findall(r"^```python\n(.*?)^```", section, re.M | re.S)


def test_the_recipe_of_architecture_md_runs_as_written(tmp_path, monkeypatch, capsys):
    blocks = _recipe()
    assert len(blocks) == 2 and blocks[0].startswith("# my_lab/linear_kind.py\n")
    monkeypatch.chdir(tmp_path)
    module = types.ModuleType("my_lab_linear_kind")  # the recipe's file, as Python imports it
    monkeypatch.setitem(sys.modules, module.__name__, module)
    try:
        for block in blocks:
            code = compile(block, str(ARCHITECTURE), "exec", dont_inherit=True)
            exec(code, module.__dict__)
    finally:
        if "my_lab.controller.linear" in registered_kinds():
            unregister_controller_kind("my_lab.controller.linear")
    out = capsys.readouterr().out.strip().splitlines()
    evaluated, evolved = json.loads(out[0]), json.loads(out[-1])
    assert evaluated["trials"] == 10 and evaluated["junctions"] > 0
    assert np.isfinite(evolved["best fitness"])
    assert json.loads((tmp_path / "linear.json").read_text())["kind"] == "my_lab.controller.linear"
    assert (tmp_path / "linear.png").read_bytes()[:4] == b"\x89PNG"
    best = json.loads((tmp_path / "evolved.json").read_text())
    assert best["kind"] == "my_lab.controller.linear" and len(best["A"]) == 2
