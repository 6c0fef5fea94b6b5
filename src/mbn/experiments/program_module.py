"""The program module (PM) and the whole Multiple Behavior Network (MBN = PM + IM).

The PM is a small CTRNN whose inputs are the camera's reading, encoded as two inputs (a
one-colour tile in view, a two-colour tile in view), and whose K output neurons' firing rates
are the program fed to the interpreter's K program inputs. To keep "the program of the last tile
seen until another tile is seen" it needs memory: biases are genes, so that neurons can be
bistable (self-excitation above 4 with a bias near minus half of it latches).

Training (paper, section 3.2): DE, population 18, initial weights in [-10, 10]; two trials per
individual on the crossroads, one with one-colour tiles scored as a right-follower and one with
two-colour tiles scored as a left-follower; the reward is the product of the two. The tile lies
one cell north of the start: the camera sees it at once, the robot drives over it, and the
junction comes 2.4 m later, out of the tile's sight — so the program must be remembered.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from mbn.control import MotorMap
from mbn.ctrnn import CTRNN
from mbn.errors import MbnInputError
from mbn.experiments.controllers import MBNControllerState as MBNState
from mbn.experiments.controllers import make_mbn_controller
from mbn.experiments.crossroads import CrossroadTask, TaskArrays
from mbn.experiments.evolve import _tile_fitness
from mbn.world.engine import CameraConfig
from mbn.world.rollout import EpisodeStats, rollout

__all__ = ["MBNState", "PMGenome", "mbn_controller", "pm_fitness"]


@dataclass(frozen=True)
class PMGenome:
    """Genes of a program module with ``programs`` output neurons: W (K x K), WE (K x 2) and
    biases (K), row-major; all neurons share ``tau`` (seconds)."""

    programs: int = 3
    tau: float = 0.5

    def __post_init__(self) -> None:
        if self.programs < 1:
            raise MbnInputError(f"programs must be >= 1, got {self.programs}")
        if not self.tau > 0:
            raise MbnInputError(f"tau must be > 0, got {self.tau}")

    @property
    def size(self) -> int:
        k = self.programs
        return k * k + 2 * k + k

    def network(self, genes: Array) -> CTRNN:
        """The PM network(s) of genes ``(..., size)``."""
        genes = jnp.asarray(genes)
        k = self.programs
        batch = genes.shape[:-1]
        W = genes[..., : k * k].reshape(*batch, k, k)
        WE = genes[..., k * k : k * k + 2 * k].reshape(*batch, k, 2)
        bias = genes[..., k * k + 2 * k :]
        return CTRNN(
            W=W,
            WE=WE,
            tau=jnp.full((*batch, k), self.tau, genes.dtype),
            bias=bias,
            gain=jnp.ones((*batch, k), genes.dtype),
        )


def mbn_controller(
    *,
    programs: int = 3,
    dt: float = 0.1,
    im_substeps: int = 20,
    pm_substeps: int = 4,
    motor: MotorMap | None = None,
) -> Callable[[MBNState, Any], tuple[MBNState, tuple[Array, Array]]]:
    """The MBN as a controller whose program is the firing rates of the PM's first ``programs``
    neurons (:func:`mbn.experiments.controllers.make_mbn_controller`)."""
    return make_mbn_controller(
        program_neurons=range(programs),
        dt=dt,
        substeps=im_substeps,
        pm_substeps=pm_substeps,
        motor=motor,
    )


def _run(
    genome: PMGenome,
    im: CTRNN,
    population: Array,
    arrays: TaskArrays,
    task: CrossroadTask,
    controller: Callable[[MBNState, Any], tuple[MBNState, tuple[Array, Array]]],
    camera: CameraConfig,
) -> EpisodeStats:
    p, e = population.shape[0], arrays.episodes
    n = p * e
    pm = genome.network(jnp.repeat(population, e, 0))
    dtype = population.dtype
    im_b = jax.tree.map(lambda a: jnp.broadcast_to(a.astype(dtype), (n, *a.shape)), im)
    state = MBNState(
        pm,
        jnp.zeros((n, genome.programs), dtype),
        im_b,
        jnp.zeros((n, im.num_neurons), dtype),
    )
    config = task.rollout_config(camera=camera)
    return rollout(
        arrays.world,
        controller,
        state,
        jnp.asarray(np.tile(arrays.poses, (p, 1)), dtype),
        jnp.asarray(np.tile(arrays.maze_index, p)),
        config,
        junctions=arrays.junctions,
    ).stats


def pm_fitness(
    genome: PMGenome,
    im: CTRNN,
    *,
    variants: int = 3,
    seed: int = 0,
    im_substeps: int = 20,
    camera: CameraConfig | None = None,
) -> Callable[[Array], Array]:
    """The paper's PM reward: (right-rule fitness with one-colour tiles) x (left-rule fitness with
    two-colour tiles), each summed over the crossroads (branch fitness, clipped at 0 so the
    product is meaningful). ``im`` is the interpreter's fixed network; ``camera`` the blob
    finder's settings (default :class:`~mbn.world.engine.CameraConfig`)."""
    camera = camera or CameraConfig()
    right = CrossroadTask(rule="right", tile=1, variants=variants, seed=seed)
    left = CrossroadTask(rule="left", tile=2, variants=variants, seed=seed)
    ar, al = right.arrays(), left.arrays()
    fr, fl = _tile_fitness(ar), _tile_fitness(al)
    controller = mbn_controller(programs=genome.programs, dt=right.dt, im_substeps=im_substeps)

    @jax.jit
    def fitness(population: Array) -> Array:
        p = population.shape[0]
        sr = fr(_run(genome, im, population, ar, right, controller, camera), right)
        sl = fl(_run(genome, im, population, al, left, controller, camera), left)
        a = jnp.clip(sr.reshape(p, ar.episodes).sum(-1), 0.0, None)
        b = jnp.clip(sl.reshape(p, al.episodes).sum(-1), 0.0, None)
        return a * b

    return fitness
