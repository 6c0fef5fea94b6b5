"""Switched controllers: K CTRNN followers, one per rule, and the rule the last tile seen puts in
force (the two baselines of the MBN, ``docs/controllers.md``, ``mbn.controller.switched``).

* ``"swap"`` (the oracle): one state of potentials whose weights are those of the network of the
  rule in force: a tile swaps the weights and keeps the potentials — what an interpreter would
  do with multipliers that cost nothing;
* ``"gate"``: the K networks run side by side on the same inputs, each with its own potentials,
  and the robot is driven by the network of the rule in force — a switch among stored followers.

The camera is read as the program module reads it (:func:`mbn.control.ctrnn.tile_inputs`: one
input per tile kind, ``[camera == 1, camera == 2, ...]``): while a tile of ``k`` colours is in
view (``k`` at most the number of tile kinds) the rule of tile kind ``k`` is in force, and it
stays so until another tile is seen.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import jax
import jax.numpy as jnp
from jax import Array

from mbn.control.ctrnn import (
    NETWORK_SUBSTEPS,
    CTRNNState,
    MotorMap,
    ctrnn_controller,
    tile_inputs,
)
from mbn.errors import MbnInputError
from mbn.memo import memoized
from mbn.networks.ctrnn import CTRNN
from mbn.world.sensors import NoiseConfig

if TYPE_CHECKING:
    from mbn.world.rollout import Shared

__all__ = ["MODES", "NO_RULE", "SwitchedState", "latched_rule", "switched_controller"]

#: How a switched controller changes network (module docstring).
MODES = ("swap", "gate")
#: The state's rule before the first tile when no rule is in force.
NO_RULE = -1


class SwitchedState(NamedTuple):
    """A switched controller's state for one robot.

    Attributes:
        nets: the K networks stacked (each array with a leading axis of K; held for the whole
            batch, :class:`mbn.world.rollout.Shared`).
        y: the potentials: ``(n,)`` for ``"swap"`` (one state, swapped between networks),
            ``(K, n)`` for ``"gate"`` (one per network).
        rule: the index of the network of the rule in force (an int32 scalar), or
            :data:`NO_RULE` before the first tile when none is.
    """

    nets: CTRNN | Shared
    y: Array
    rule: Array


def latched_rule(camera: Array, rule: Array, tile_networks: Array) -> Array:
    """The rule in force after a step whose camera reads ``camera``: the network of the tile in
    view (``tile_networks[k - 1]`` for a tile of ``k`` colours, one of the tile kinds read by
    :func:`mbn.control.ctrnn.tile_inputs`), else ``rule`` unchanged."""
    seen = tile_inputs(camera, tile_networks.shape[0], jnp.int32)
    return jnp.where(seen.any(-1), tile_networks[jnp.argmax(seen, -1)], rule)


def _network_obs(obs: Any, k: int, noise: NoiseConfig | None) -> Any:
    """The observation network ``k`` of a gate reads: its neuron noise from ``obs.key`` folded
    with ``k`` (network 0: ``obs.key`` itself, as a plain CTRNN draws it)."""
    if k == 0 or noise is None or noise.neuron_std <= 0 or getattr(obs, "key", None) is None:
        return obs
    return obs._replace(key=jax.random.fold_in(obs.key, k))


@memoized
def switched_controller(
    *,
    mode: str,
    tile_networks: Sequence[int],
    dt: float = 0.1,
    substeps: int = NETWORK_SUBSTEPS,
    motor: MotorMap | None = None,
    method: str = "euler",
    noise: NoiseConfig | None = None,
) -> Callable[[SwitchedState, Any], tuple[SwitchedState, tuple[Array, Array]]]:
    """A switched controller ``(state, obs) -> (state, (v, w))`` for one robot.

    Each robot step the rule in force is latched from the camera (:func:`latched_rule`;
    ``tile_networks``: the network index of a tile of 1, 2, ... colours), then every network
    integrates I1..I3 for ``dt`` as :func:`mbn.control.ctrnn.ctrnn_controller` does
    (``substeps`` steps of ``method``, ``noise.neuron_std`` on the potentials): in ``"swap"``
    mode each from the one state, which takes the potentials of the network of the rule in
    force (the same as integrating it with that network alone); in ``"gate"`` mode each from
    its own potentials (network ``k``'s noise drawn from ``obs.key`` folded with ``k``). The
    motor commands are those of the network of the rule in force; before the first tile, with
    no rule in force (:data:`NO_RULE`), those of the network of a one-colour tile.
    """
    if mode not in MODES:
        raise MbnInputError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    tiles = tuple(int(k) for k in tile_networks)
    if not tiles or min(tiles) < 0:
        raise MbnInputError(f"tile_networks: one network index per tile kind, got {tiles}")
    index = jnp.asarray(tiles, jnp.int32)
    inner = ctrnn_controller(dt=dt, substeps=substeps, motor=motor, method=method, noise=noise)
    swap = mode == "swap"

    def control(state: SwitchedState, obs: Any) -> tuple[SwitchedState, tuple[Array, Array]]:
        nets: Any = state.nets  # the rollout hands a controller plain networks
        count = int(nets.W.shape[0])
        rule = latched_rule(obs.camera, state.rule, index)
        driving = jnp.where(rule < 0, index[0], rule)
        ys, vs, ws = [], [], []
        for k in range(count):
            net = jax.tree.map(lambda a, k=k: a[k], nets)
            y = state.y if swap else state.y[k]
            moved, (v, w) = inner(CTRNNState(net, y), obs if swap else _network_obs(obs, k, noise))
            ys.append(moved.y)
            vs.append(v)
            ws.append(w)
        every = jnp.stack(ys)
        y_next = every[driving] if swap else every
        v, w = jnp.stack(vs)[driving], jnp.stack(ws)[driving]
        return SwitchedState(state.nets, y_next, rule), (v, w)

    return control
