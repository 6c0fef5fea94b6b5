"""Controllers ready to run: :func:`make_controller` turns a spec (:mod:`mbn.controllers.spec`, or
a registered kind's, :mod:`mbn.controllers.kinds`) into a :class:`LoadedController` for
:func:`mbn.experiments.trials.run_trials`, by its kind's runner (:func:`ctrnn_runner`,
:func:`interpreter_runner`, :func:`mbn_runner`, :func:`switched_runner` for ``mbn``'s kinds);
:func:`load_controller` reads a file first (:mod:`mbn.controllers.codec`)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jax.numpy as jnp
import numpy as np
from jax import Array

from mbn.control.ctrnn import (
    CTRNNState,
    ProgrammedState,
    ctrnn_controller,
    interpreter_controller,
    with_tiles,
)
from mbn.control.mbn import MBNControllerState, make_mbn_controller
from mbn.control.switched import NO_RULE, SwitchedState, switched_controller
from mbn.controllers.codec import read_controller_spec
from mbn.controllers.kinds import Runner, kind_of
from mbn.controllers.spec import (
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    MBNControllerSpec,
    SwitchedControllerSpec,
)
from mbn.errors import MbnInputError
from mbn.host import put
from mbn.networks.ctrnn import CTRNN, Method, max_stable_dt
from mbn.world.engine import CameraConfig
from mbn.world.rollout import Shared
from mbn.world.sensors import NoiseConfig, SensorConfig

__all__ = [
    "MAX_NETWORK_STEPS",
    "MAX_TRIAL_STEPS",
    "Controller",
    "LoadedController",
    "check_step",
    "check_trial_length",
    "ctrnn_runner",
    "ctrnn_step_beyond_limit",
    "interpreter_runner",
    "load_controller",
    "make_controller",
    "mbn_runner",
    "step_beyond_limit",
    "switched_runner",
    "switched_step_beyond_limit",
]

#: A controller for one robot: ``(state, observation) -> (state, (v, w))``.
Controller = Callable[[Any, Any], tuple[Any, tuple[Array, Array]]]


@dataclass(frozen=True, eq=False)
class LoadedController:
    """A controller ready to run (:func:`mbn.experiments.trials.run_trials`).

    Attributes:
        kind: the file's kind (a registered kind's name, :mod:`mbn.controllers.kinds`).
        controller: ``(state, obs) -> (state, (v, w))`` for one robot.
        initial_state: ``n -> `` the batched initial state of ``n`` robots (potentials at 0;
            the whole MBN's program module starts from its file's ``initial`` potentials when
            it has them; the networks are :class:`mbn.world.rollout.Shared` by the batch: map
            the controller over it with :func:`mbn.world.rollout.map_controller`, as the rollout
            does).
        sensors: the sonars to cast and their normalisation.
        dt: the robot step (s).
        needs_camera: whether the controller reads the camera (the whole MBN, a CTRNN with
            tile rules, a switched controller).
        camera: the camera settings it reads (None when it reads none).
        programs: the file's named programs (empty for a plain CTRNN).
        program: the program in use (None for a plain CTRNN or the whole MBN).
        behavior: the behaviour a plain CTRNN file declares (else None).
        initial_rule: for the whole MBN and a switched controller, the rule it follows before
            its first tile (its file's ``initial``; None for a file without one: an MBN starts at
            rest with no rule).
        tile_rules: for the whole MBN, a CTRNN that reads the tiles and a switched controller,
            the rule a tile of 1, 2, ... colours puts in force (its file's; the paper's right,
            left); None for the others.
        spec: the parsed file.
        noise: the noise it runs under (all zero: none).
        network_steps: the network steps it takes each robot step (its ``substeps``, plus the
            program module's for the whole MBN, times the networks of a switched controller;
            :func:`check_trial_length`).
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
    initial_rule: str | None
    spec: Any
    tile_rules: tuple[str, ...] | None = None
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    network_steps: int = 1


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
        values = _looks_like_values(program)
        raise MbnInputError(
            f"{where}: no program {program!r} (the file has: {names})"
            + ("; a program is chosen by its name, not written as values" if values else "")
        )
    return program


def _looks_like_values(text: str) -> bool:
    """Whether a program name reads as numbers (``"0.5,0.2,0.9"``): values, not a name."""
    parts = text.replace(",", " ").split()
    try:
        [float(p) for p in parts]
    except ValueError:
        return False
    return bool(parts)


def _ctrnn_parts(
    spec: CTRNNControllerSpec, noise: NoiseConfig | None
) -> tuple[Controller, Callable[[int], Any]]:
    net = spec.net
    control = ctrnn_controller(
        dt=spec.dt,
        substeps=spec.substeps,
        motor=spec.motor,
        method=spec.method,
        noise=noise,
        inputs=None if spec.tile_rules is None else with_tiles(len(spec.tile_rules)),
    )

    def initial(n: int) -> CTRNNState:
        return CTRNNState(Shared(net), put(np.zeros((n, net.num_neurons), net.dtype)))

    return control, initial


def _mbn_parts(
    spec: MBNControllerSpec, noise: NoiseConfig | None
) -> tuple[Controller, Callable[[int], Any]]:
    im_spec = spec.interpreter_spec
    im, pm = _simulated(im_spec), spec.program_module
    control = make_mbn_controller(
        program_neurons=spec.program_neurons,
        readout=None if spec.readout is None else np.asarray(spec.readout, np.float64),
        dt=im_spec.dt,
        substeps=im_spec.substeps,
        pm_substeps=spec.pm_substeps,
        motor=im_spec.motor,
        method=im_spec.method,
        noise=noise,
    )

    if spec.initial is None:  # a file without ``initial``: at rest
        pm_y0 = jnp.zeros((pm.num_neurons,), pm.dtype)
    else:
        pm_y0 = jnp.asarray(spec.initial.potentials, pm.dtype)

    def initial(n: int) -> MBNControllerState:
        return MBNControllerState(
            Shared(pm),
            put(np.broadcast_to(np.asarray(pm_y0), (n, pm.num_neurons))),
            Shared(im),
            put(np.zeros((n, im.num_neurons), im.dtype)),
        )

    return control, initial


def _switched_parts(
    spec: SwitchedControllerSpec, noise: NoiseConfig | None
) -> tuple[Controller, Callable[[int], Any]]:
    control = switched_controller(
        mode=spec.mode,
        tile_networks=spec.tile_networks,
        dt=spec.dt,
        substeps=spec.substeps,
        motor=spec.motor,
        method=spec.method,
        noise=noise,
    )
    nets = list(spec.networks.values())
    stacked = CTRNN(
        **{
            name: put(np.stack([np.asarray(getattr(net, name)) for net in nets]))
            for name in ("W", "WE", "tau", "bias", "gain")
        }
    )
    n, dtype = spec.num_neurons, nets[0].dtype
    shape = (n,) if spec.mode == "swap" else (len(nets), n)
    rule = NO_RULE if spec.initial is None else spec.rules.index(spec.initial)

    def initial(b: int) -> SwitchedState:
        return SwitchedState(
            Shared(stacked),
            put(np.zeros((b, *shape), dtype)),
            put(np.full((b,), rule, np.int32)),
        )

    return control, initial


def _simulated(im_spec: InterpreterControllerSpec) -> Any:
    """The network a controller integrates: the dense interpreter or its blocks."""
    interp = im_spec.interpreter
    return interp.blocks() if im_spec.simulation == "blocks" else interp.net


def _interpreter_parts(
    im_spec: InterpreterControllerSpec, program: tuple[float, ...], noise: NoiseConfig | None
) -> tuple[Controller, Callable[[int], Any]]:
    net = _simulated(im_spec)
    values = jnp.asarray(program, net.dtype)
    control = interpreter_controller(
        dt=im_spec.dt,
        substeps=im_spec.substeps,
        motor=im_spec.motor,
        method=im_spec.method,
        noise=noise,
    )

    def initial(n: int) -> ProgrammedState:
        return ProgrammedState(
            Shared(net),
            put(np.zeros((n, net.num_neurons), net.dtype)),
            put(np.broadcast_to(np.asarray(values), (n, values.shape[0]))),
        )

    return control, initial


def ctrnn_step_beyond_limit(spec: CTRNNControllerSpec, where: str = "controller") -> str | None:
    """Why a plain CTRNN controller's network step (``dt / substeps``) is beyond the stability
    limit of its integrator (:func:`mbn.networks.ctrnn.check_dt`), with how many substeps would
    do; None where it is within (the integration follows the network's dynamics)."""
    method: Method = "rk4" if spec.method == "rk4" else "euler"
    h = spec.dt / spec.substeps
    limit = max_stable_dt(spec.net, method)  # once: for a large network it is the costly part
    # the verdict of check_dt(on_unstable="raise"): a step above a finite limit
    if not (math.isfinite(limit) and h / limit > 1.0):
        return None
    need = math.ceil(spec.dt / limit)
    return (
        f"{where}: its network's step {h * 1000:.3g} ms (dt {spec.dt:g} s / {spec.substeps} "
        f"substeps) is above the stability limit {limit * 1000:.3g} ms of its integrator; "
        f"it needs substeps >= {need}"
    )


def switched_step_beyond_limit(
    spec: SwitchedControllerSpec, where: str = "controller"
) -> str | None:
    """:func:`ctrnn_step_beyond_limit` of each network of a switched controller (the first beyond
    its limit, naming it), or None where every one is within."""
    for rule, net in spec.networks.items():
        follower = CTRNNControllerSpec(
            net,
            sensors=spec.sensors,
            motor=spec.motor,
            dt=spec.dt,
            substeps=spec.substeps,
            method=spec.method,
        )
        message = ctrnn_step_beyond_limit(follower, f"{where}: networks.{rule}")
        if message is not None:
            return message
    return None


def step_beyond_limit(spec: Any, where: str = "controller") -> str | None:
    """Why a controller's integration step is beyond its stability limit, by its kind
    (:meth:`mbn.controllers.kinds.ControllerKind.step_beyond_limit`; for a plain CTRNN
    :func:`ctrnn_step_beyond_limit`); None where it is within, or for a spec of no registered
    kind.

    Interpreter and MBN files are not checked: the limit is estimated at the corners of the
    sigmoids' slopes, which for the multiplier sub-networks lies far below the step they run
    and are verified at (the interpreter's agreement with its networks, ``docs/programmable.md``).
    """
    kind = kind_of(spec)
    return None if kind is None else kind.step_beyond_limit(spec, where)


def check_step(spec: Any, where: str = "controller") -> None:
    """Refuse a controller whose network step is beyond its integrator's stability limit
    (:func:`step_beyond_limit`, whose message it raises)."""
    message = step_beyond_limit(spec, where)
    if message is not None:
        raise MbnInputError(message)


#: The most robot steps (``seconds / dt``) one trial may take: a trial of the paper's protocol
#: takes 900 (90 s at Stage's 0.1 s), the longest ``mbn evaluate --seconds`` allows 360 000; a
#: million robot steps take about a minute on a CPU.
MAX_TRIAL_STEPS = 1_000_000
#: The most network steps one trial may take: its robot steps times the network steps of each
#: (the controller's ``substeps``, plus the program module's for the whole MBN). The paper's
#: protocol takes 18 000 (20 substeps), the interpreter at 80 substeps 72 000.
MAX_NETWORK_STEPS = 100_000_000


def network_steps_per_robot_step(loaded: LoadedController) -> int:
    """The network steps a controller takes each robot step: its ``substeps``, plus the program
    module's for the whole MBN (:attr:`mbn.controllers.kinds.Runner.network_steps`)."""
    return loaded.network_steps


def check_trial_length(
    loaded: LoadedController,
    seconds: float,
    where: str = "controller",
    *,
    limit_name: str = "the time limit",
) -> None:
    """Refuse a trial of ``seconds`` that would take more than :data:`MAX_TRIAL_STEPS` robot
    steps at the controller's ``dt``, or more than :data:`MAX_NETWORK_STEPS` network steps
    (:func:`network_steps_per_robot_step`), in one line naming the limit and what to change
    (``limit_name``: what sets ``seconds``, e.g. ``--seconds``). The count is the rollout's:
    ``max(1, round(seconds / dt))`` robot steps."""
    if not (isinstance(seconds, (int, float)) and math.isfinite(seconds) and seconds > 0):
        raise MbnInputError(f"{where}: the time limit must be a finite number > 0, got {seconds!r}")
    steps = max(1, round(seconds / loaded.dt))
    if steps > MAX_TRIAL_STEPS:
        raise MbnInputError(
            f"{where}: a trial of {seconds:g} s at its dt {loaded.dt:g} s is {steps:,} robot "
            f"steps, above the limit of {MAX_TRIAL_STEPS:,} a trial may take: raise its dt or "
            f"lower {limit_name}"
        )
    per_step = network_steps_per_robot_step(loaded)
    if steps * per_step > MAX_NETWORK_STEPS:
        raise MbnInputError(
            f"{where}: a trial of {seconds:g} s is {steps:,} robot steps x {per_step:,} network "
            f"steps = {steps * per_step:,}, above the limit of {MAX_NETWORK_STEPS:,} network steps "
            f"a trial may take: lower its substeps or {limit_name}"
        )


def ctrnn_runner(
    spec: CTRNNControllerSpec, program: str | None, noise: NoiseConfig | None, where: str
) -> Runner:
    """A plain CTRNN controller ready to run (a monolithic one reads the camera itself)."""
    if program is not None:
        raise MbnInputError(
            f"{where}: a plain CTRNN controller has no programs (got program {program!r})"
        )
    control, initial = _ctrnn_parts(spec, noise)
    return Runner(
        controller=control,
        initial_state=initial,
        sensors=spec.sensors,
        dt=spec.dt,
        camera=spec.camera if spec.tile_rules is not None else None,
        behavior=spec.behavior,
        tile_rules=spec.tile_rules,
        network_steps=spec.substeps,
    )


def interpreter_runner(
    spec: InterpreterControllerSpec, program: str | None, noise: NoiseConfig | None, where: str
) -> Runner:
    """The interpreter running one of its programs (``program``; may be omitted when it has one
    only)."""
    programs = _programs_of(spec)
    chosen = _choose_program(programs, program, spec.kind, where)
    control, initial = _interpreter_parts(spec, programs[chosen], noise)
    return Runner(
        controller=control,
        initial_state=initial,
        sensors=spec.sensors,
        dt=spec.dt,
        programs=programs,
        program=chosen,
        network_steps=spec.substeps,
    )


def mbn_runner(
    spec: MBNControllerSpec, program: str | None, noise: NoiseConfig | None, where: str
) -> Runner:
    """The whole MBN (``program`` None: program module, camera and interpreter), or its
    interpreter alone with the stored program ``program``."""
    im_spec = spec.interpreter_spec
    programs = _programs_of(im_spec)
    if program is not None:
        chosen = _choose_program(programs, program, spec.kind, where)
        control, initial = _interpreter_parts(im_spec, programs[chosen], noise)
        return Runner(
            controller=control,
            initial_state=initial,
            sensors=im_spec.sensors,
            dt=im_spec.dt,
            programs=programs,
            program=chosen,
            tile_rules=spec.tile_rules,
            network_steps=im_spec.substeps,
        )
    control, initial = _mbn_parts(spec, noise)
    return Runner(
        controller=control,
        initial_state=initial,
        sensors=im_spec.sensors,
        dt=im_spec.dt,
        camera=spec.camera,
        programs=programs,
        initial_rule=spec.initial.rule if spec.initial is not None else None,
        tile_rules=spec.tile_rules,
        network_steps=im_spec.substeps + spec.pm_substeps,
    )


def switched_runner(
    spec: SwitchedControllerSpec, program: str | None, noise: NoiseConfig | None, where: str
) -> Runner:
    """A switched controller ready to run: its followers, switched by the tiles its camera
    sees."""
    if program is not None:
        raise MbnInputError(
            f"{where}: a switched controller has no programs (got program {program!r}); its "
            f"networks are switched by the tiles ({', '.join(spec.rules)})"
        )
    control, initial = _switched_parts(spec, noise)
    return Runner(
        controller=control,
        initial_state=initial,
        sensors=spec.sensors,
        dt=spec.dt,
        camera=spec.camera,
        initial_rule=spec.initial,
        tile_rules=spec.tile_rules,
        network_steps=spec.substeps * len(spec.networks),
    )


def make_controller(
    spec: Any,
    program: str | None = None,
    *,
    where: str = "controller",
    check_stability: bool = True,
    noise: NoiseConfig | None = None,
) -> LoadedController:
    """A :class:`LoadedController` for a spec, by its kind's runner
    (:meth:`ControllerKind.runner <mbn.controllers.kinds.ControllerKind.runner>`).

    ``program``: for an interpreter, the name of the program to run (may be omitted when there
    is only one); for an MBN, None runs the whole MBN (program module and camera) and a name runs
    the interpreter alone with that stored program; for a plain CTRNN it must be None.
    ``check_stability``: refuse a network step beyond the integrator's stability limit
    (:func:`check_step`). ``noise``: the noise the controller runs under
    (:class:`mbn.world.sensors.NoiseConfig`; None or all zero: none): the controller draws its
    own channels (neurons, program lines), and the trials that run it the world's.
    """
    kind = kind_of(spec)
    if kind is None:
        raise MbnInputError(f"{where}: not a controller spec: {type(spec).__name__}")
    if check_stability:
        message = kind.step_beyond_limit(spec, where)
        if message is not None:
            raise MbnInputError(message)
    run = kind.runner(spec, program, noise, where)
    return LoadedController(
        kind=kind.name,
        controller=run.controller,
        initial_state=run.initial_state,
        sensors=run.sensors,
        dt=run.dt,
        needs_camera=run.camera is not None,
        camera=run.camera,
        programs=dict(run.programs),
        program=run.program,
        behavior=run.behavior,
        initial_rule=run.initial_rule,
        spec=spec,
        tile_rules=run.tile_rules,
        noise=noise if noise is not None else NoiseConfig(),
        network_steps=run.network_steps,
    )


def load_controller(
    path: str | Path,
    program: str | None = None,
    *,
    check_stability: bool = True,
    noise: NoiseConfig | None = None,
) -> LoadedController:
    """Read a controller file and make it ready to run (see :func:`make_controller` for
    ``program``, ``check_stability`` and ``noise``). Errors are one line naming the file."""
    return make_controller(
        read_controller_spec(path),
        program,
        where=str(path),
        check_stability=check_stability,
        noise=noise,
    )
