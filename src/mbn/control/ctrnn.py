"""Robot controllers built from CTRNNs, in the form the rollout expects.

A controller is a pure function ``(state, observation) -> (state, (v, w))`` for one robot. For a
CTRNN the state holds the network's parameters and its potentials, so a batch of genomes is a
batch of states. The paper's motor mapping (section 3.1): the third neuron sets the linear speed
and the second the angular speed; ``mbn`` uses ``v = v_max * sigma(y3)`` and
``w = w_max * (2 sigma(y2) - 1)`` (positive turns left), with v_max = 0.5 m/s (the P3DX limit) and
w_max = 1 rad/s.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple, cast

import jax
import jax.numpy as jnp
from jax import Array

from mbn.errors import MbnInputError
from mbn.memo import memoized
from mbn.networks.ctrnn import CTRNN, euler_step, euler_steps, firing_rate, integrator, rk4_step
from mbn.networks.structured import BlockNet, block_euler_steps, block_field, block_rates
from mbn.world.sensors import NoiseConfig

if TYPE_CHECKING:
    from mbn.world.rollout import Shared

__all__ = [
    "NETWORK_SUBSTEPS",
    "CTRNNState",
    "MotorMap",
    "ProgrammedState",
    "ShadowedState",
    "ctrnn_controller",
    "interpreter_controller",
    "shadowed",
    "substeps_for",
]

#: Network steps per 0.1 s robot step for the followers and the program module: h = 5 ms, so
#: h / tau = 0.01 for the followers (tau = 0.5 s), fine enough that an evolved network's
#: behaviour is the CTRNN's, not its Euler map's (at 4 steps it was not: docs/reproduce.md);
#: and h / tau_m = 0.1 for multipliers at the paper's tau / 10 (the step they were trained
#: with). ``mbn reproduce`` runs its interpreters' multipliers at tau / 40 with 80 steps
#: (``[interpreter]``, docs/reproduce.md).
NETWORK_SUBSTEPS = 20


@dataclass(frozen=True)
class MotorMap:
    """How neuron outputs become ``(v, w)``: 0-based neuron indices and scales."""

    speed_neuron: int = 2
    turn_neuron: int = 1
    v_max: float = 0.5
    w_max: float = 1.0

    def __post_init__(self) -> None:
        if self.speed_neuron < 0 or self.turn_neuron < 0:
            raise MbnInputError("motor neurons must be indices >= 0")
        if not (self.v_max > 0 and self.w_max > 0):
            raise MbnInputError(f"v_max and w_max must be > 0, got {self.v_max}, {self.w_max}")


class CTRNNState(NamedTuple):
    """A CTRNN controller's state: the network (weights, tau, ...; or an interpreter by its
    blocks, :class:`mbn.networks.structured.BlockNet`) and its potentials ``y``."""

    net: CTRNN | BlockNet | Shared
    y: Array


def substeps_for(dt: float, tau: float, max_ratio: float = 0.05) -> int:
    """Sub-steps per robot step ``dt`` that keep ``h / tau <= max_ratio``."""
    if not (dt > 0 and tau > 0 and max_ratio > 0):
        raise MbnInputError(f"need dt, tau, max_ratio > 0, got {dt}, {tau}, {max_ratio}")
    return max(1, math.ceil(dt / (tau * max_ratio) - 1e-9))


@memoized
def ctrnn_controller(
    *,
    dt: float = 0.1,
    substeps: int = 4,
    motor: MotorMap | None = None,
    method: str = "euler",
    inputs: Callable[[Any], Array] | None = None,
    noise: NoiseConfig | None = None,
) -> Callable[[CTRNNState, Any], tuple[CTRNNState, tuple[Array, Array]]]:
    """A controller that integrates a CTRNN for ``dt`` seconds in ``substeps`` steps with the
    observation's inputs held, then reads the motor neurons.

    Args:
        dt: the robot step (seconds).
        substeps: network steps per robot step (see :func:`substeps_for`).
        motor: the motor mapping (default :class:`MotorMap`).
        method: "euler" or "rk4".
        inputs: observation -> network inputs; default the paper's I1..I3 (``obs.inputs``).
        noise: ``noise.neuron_std`` > 0 adds Gaussian noise of that std to every potential once
            per robot step, after the sub-steps (drawn from ``obs.key``, folded with 0).
    """
    if substeps < 1:
        raise MbnInputError(f"substeps must be >= 1, got {substeps}")
    if method not in ("euler", "rk4"):
        raise MbnInputError(f"method must be euler or rk4, got {method!r}")
    motor = motor or MotorMap()
    h = dt / substeps
    stepper = euler_step if method == "euler" else rk4_step
    read = inputs or (lambda obs: obs.inputs)

    def control(state: CTRNNState, obs: Any) -> tuple[CTRNNState, tuple[Array, Array]]:
        u = read(obs)
        y = state.y
        held = state.net  # the rollout hands a controller plain networks
        if isinstance(held, BlockNet):  # an interpreter simulated by its structure
            if method == "euler":
                y = block_euler_steps(held, y, u, h, substeps)
            else:
                blocks, rk4 = held, integrator("rk4")
                for _ in range(substeps):
                    y = rk4(lambda z: block_field(blocks, z, u), y, h)
            y = with_neuron_noise(y, obs, noise, 0)
            rate = block_rates(held, y)
        else:
            net = cast(CTRNN, held)
            if method == "euler":
                y = euler_steps(net, y, u, h, substeps)  # a held network: neuron-major
            else:
                for _ in range(substeps):
                    y = stepper(net, y, u, h)
            y = with_neuron_noise(y, obs, noise, 0)
            rate = firing_rate(net, y)
        v = motor.v_max * rate[..., motor.speed_neuron]
        w = motor.w_max * (2.0 * rate[..., motor.turn_neuron] - 1.0)
        return CTRNNState(state.net, y), (v, w)

    return control


class ProgrammedState(NamedTuple):
    """An interpreter controller's state: the fixed-weight network, its potentials, and the
    program fed to its program inputs (``(K,)`` in [0, 1])."""

    net: CTRNN | BlockNet | Shared
    y: Array
    program: Array


@memoized
def interpreter_controller(
    *,
    dt: float = 0.1,
    substeps: int = NETWORK_SUBSTEPS,
    motor: MotorMap | None = None,
    method: str = "euler",
    noise: NoiseConfig | None = None,
) -> Callable[[ProgrammedState, Any], tuple[ProgrammedState, tuple[Array, Array]]]:
    """A controller for a programmable interpreter (:mod:`mbn.networks.programmable`): its
    inputs are the paper's I1..I3 followed by the state's program; the motor neurons are the
    original network's (the interpreter puts them first). ``substeps`` must keep h / tau_m = 0.1,
    the multipliers' training step: the default 20 sub-steps of 5 ms for multipliers at tau/10
    and tau = 0.5 s, 80 for tau/40. ``noise``: ``neuron_std`` as :func:`ctrnn_controller`;
    ``program_std`` > 0 adds Gaussian noise to the program lines each robot step (clipped to
    [0, 1]; ``obs.key`` folded with 1): the state keeps the clean program."""
    inner = ctrnn_controller(dt=dt, substeps=substeps, motor=motor, method=method, noise=noise)

    def control(state: ProgrammedState, obs: Any) -> tuple[ProgrammedState, tuple[Array, Array]]:
        program = state.program.astype(obs.inputs.dtype)
        if noise is not None and noise.program_std > 0:
            e = jax.random.normal(_noise_key(obs, 1), program.shape, program.dtype)
            program = jnp.clip(program + noise.program_std * e, 0.0, 1.0)
        u = jnp.concatenate([obs.inputs, program], axis=-1)
        inner_state, vw = inner(CTRNNState(state.net, state.y), obs._replace(inputs=u))
        return ProgrammedState(state.net, inner_state.y, state.program), vw

    return control


class ShadowedState(NamedTuple):
    """A controller's state with reference networks riding along (:func:`shadowed`): the inner
    controller's state, the references' (network ``(R, ...)`` and potentials ``(R, n)``), and the
    motor mismatch with each reference summed over the steps so far (``(R,)``)."""

    inner: Any
    references: CTRNNState
    mismatch: Array


@memoized
def shadowed(
    controller: Callable[[Any, Any], tuple[Any, tuple[Array, Array]]],
    *,
    dt: float = 0.1,
    substeps: int = NETWORK_SUBSTEPS,
    motor: MotorMap | None = None,
) -> Callable[[ShadowedState, Any], tuple[ShadowedState, tuple[Array, Array]]]:
    """``controller`` drives the robot while reference CTRNNs read the same observations (their
    I1..I3) without driving; each step adds, for each reference, how far apart the two motor
    commands are: ``|v - v_ref| / v_max + |w - w_ref| / (2 w_max)`` (0 when they agree, at most 2).
    Divided by the number of steps, the sum is the mean motor mismatch: how closely the controller
    behaves as each reference would in its place."""
    motor = motor or MotorMap()
    reference = ctrnn_controller(dt=dt, substeps=substeps, motor=motor)

    def control(state: ShadowedState, obs: Any) -> tuple[ShadowedState, tuple[Array, Array]]:
        inner, (v, w) = controller(state.inner, obs)
        refs, (vr, wr) = reference(state.references, obs)
        d = jnp.abs(v - vr) / motor.v_max + jnp.abs(w - wr) / (2.0 * motor.w_max)
        return ShadowedState(inner, refs, state.mismatch + d), (v, w)

    return control


def _noise_key(obs: Any, channel: int) -> Array:
    key = getattr(obs, "key", None)
    if key is None:
        raise MbnInputError(
            "controller noise is on but the observation has no key: give the rollout the same "
            "noise settings and a PRNG key"
        )
    return jax.random.fold_in(key, channel)


def with_neuron_noise(y: Array, obs: Any, noise: NoiseConfig | None, channel: int) -> Array:
    """``y`` plus ``noise.neuron_std`` Gaussian noise per potential (``obs.key`` folded with
    ``channel``), or ``y`` itself when neuron noise is off."""
    if noise is None or noise.neuron_std <= 0:
        return y
    e = jax.random.normal(_noise_key(obs, channel), y.shape, y.dtype)
    return y + noise.neuron_std * e


def tile_inputs(camera: Array, kinds: int, dtype: Any) -> Array:
    """The camera's reading as one input per tile kind: ``[camera == 1, camera == 2, ...]``
    (``kinds`` of them, ``dtype``), as a program module or a monolithic controller reads it."""
    return jnp.stack([camera == t for t in range(1, kinds + 1)], axis=-1).astype(dtype)


@memoized
def with_tiles(kinds: int) -> Callable[[Any], Array]:
    """An ``inputs`` function for :func:`ctrnn_controller`: I1..I3 followed by the camera's
    :func:`tile_inputs` (a CTRNN that reads the tiles itself, ``docs/contest.md``)."""

    def read(obs: Any) -> Array:
        return jnp.concatenate(
            [obs.inputs, tile_inputs(obs.camera, kinds, obs.inputs.dtype)], axis=-1
        )

    return read


def initial_state(net: CTRNN) -> CTRNNState:
    """Potentials at rest (0) for a network (batched or not)."""
    return CTRNNState(net, jnp.zeros(net.tau.shape, net.tau.dtype))


__all__ += ["initial_state", "tile_inputs", "with_neuron_noise", "with_tiles"]
