"""The Multiple Behavior Network's dynamics: the program module (PM) reads the camera and writes
the program of the interpreter (IM), which drives the robot (paper section 3.2)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple, cast

import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from mbn.control.ctrnn import (
    NETWORK_SUBSTEPS,
    MotorMap,
    ProgrammedState,
    interpreter_controller,
    tile_inputs,
    with_neuron_noise,
)
from mbn.errors import MbnInputError
from mbn.memo import memoized
from mbn.networks.ctrnn import CTRNN, euler_steps, firing_rate
from mbn.world.sensors import NoiseConfig

if TYPE_CHECKING:
    from mbn.world.rollout import Shared

__all__ = ["MBNControllerState", "make_mbn_controller"]


class MBNControllerState(NamedTuple):
    """The MBN's state for one robot: the program module (network and potentials) and the
    interpreter (network and potentials)."""

    pm: CTRNN | Shared
    pm_y: Array
    im: CTRNN | Shared
    im_y: Array


@memoized
def make_mbn_controller(
    *,
    program_neurons: Sequence[int],
    dt: float = 0.1,
    substeps: int = NETWORK_SUBSTEPS,
    pm_substeps: int = 4,
    motor: MotorMap | None = None,
    method: str = "euler",
    readout: ArrayLike | None = None,
    noise: NoiseConfig | None = None,
) -> Callable[[MBNControllerState, Any], tuple[MBNControllerState, tuple[Array, Array]]]:
    """The MBN as a controller ``(state, obs) -> (state, (v, w))`` for one robot.

    Each step the program module integrates the camera reading ``[camera == 1, camera == 2,
    ...]`` (one input per tile kind: as many as the PM's inputs) for ``dt`` (``pm_substeps``
    Euler steps); the firing rates of ``program_neurons`` are the program — or, with a
    ``readout`` ``(K, P)``, the code whose program is ``clip(readout @ code, 0, 1)``; then the
    interpreter integrates I1..I3 and that program for ``dt`` as
    :func:`mbn.control.ctrnn.interpreter_controller` does (``substeps`` steps of ``method``).
    ``noise``: ``neuron_std`` on the program module's potentials (``obs.key`` folded with 2) and
    the interpreter's, ``program_std`` on the program lines (the PM's output) as the
    interpreter controller adds it.
    """
    if pm_substeps < 1:
        raise MbnInputError(f"pm_substeps must be >= 1, got {pm_substeps}")
    index = jnp.asarray(tuple(program_neurons), jnp.int32)
    R = None if readout is None else jnp.asarray(readout)
    h = dt / pm_substeps
    interpret = interpreter_controller(
        dt=dt, substeps=substeps, motor=motor, method=method, noise=noise
    )

    def control(
        state: MBNControllerState, obs: Any
    ) -> tuple[MBNControllerState, tuple[Array, Array]]:
        dtype = state.pm_y.dtype
        pm = cast(CTRNN, state.pm)  # the rollout hands a controller plain networks
        kinds = pm.WE.shape[-1]
        y = euler_steps(pm, state.pm_y, tile_inputs(obs.camera, kinds, dtype), h, pm_substeps)
        y = with_neuron_noise(y, obs, noise, 2)
        program = firing_rate(pm, y)[..., index]
        if R is not None:
            program = jnp.clip(program @ R.T.astype(dtype), 0.0, 1.0)
        im_state, vw = interpret(ProgrammedState(state.im, state.im_y, program), obs)
        return MBNControllerState(state.pm, y, state.im, im_state.y), vw

    return control
