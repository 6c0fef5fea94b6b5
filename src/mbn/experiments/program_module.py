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

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from mbn.control.ctrnn import MotorMap
from mbn.control.mbn import MBNControllerState as MBNState
from mbn.control.mbn import make_mbn_controller
from mbn.errors import MbnInputError
from mbn.experiments.crossroads import EPISODE_FITNESS_MAX, CrossroadTask, TaskArrays
from mbn.experiments.evolve import tile_fitness
from mbn.networks.ctrnn import CTRNN, euler_step, firing_rate
from mbn.paper import DEFAULT_TAU
from mbn.world.engine import CameraConfig
from mbn.world.rollout import EpisodeStats, Shared, rollout

__all__ = [
    "Latch",
    "MBNState",
    "MemoryReward",
    "PMGenome",
    "camera_inputs",
    "code_fitness",
    "latch_after_tile",
    "mbn_controller",
    "memory_reward_maximum",
    "pm_fitness",
    "pm_maze_fitness",
    "pm_memory_fitness",
    "pm_program_fitness",
    "prime",
    "start_mismatch",
    "tile_sequences",
]


@dataclass(frozen=True)
class PMGenome:
    """Genes of a program module with ``programs`` output neurons and ``inputs`` camera inputs
    (one per tile kind: 2 in the paper): W (K x K), WE (K x inputs) and biases (K), row-major;
    all neurons share ``tau`` (seconds)."""

    programs: int = 3
    tau: float = DEFAULT_TAU
    inputs: int = 2

    def __post_init__(self) -> None:
        if self.programs < 1:
            raise MbnInputError(f"programs must be >= 1, got {self.programs}")
        if not self.tau > 0:
            raise MbnInputError(f"tau must be > 0, got {self.tau}")
        if self.inputs < 1:
            raise MbnInputError(f"inputs must be >= 1, got {self.inputs}")

    @property
    def size(self) -> int:
        k = self.programs
        return k * k + self.inputs * k + k

    def network(self, genes: Array) -> CTRNN:
        """The PM network(s) of genes ``(..., size)``."""
        genes = jnp.asarray(genes)
        k, m = self.programs, self.inputs
        batch = genes.shape[:-1]
        W = genes[..., : k * k].reshape(*batch, k, k)
        WE = genes[..., k * k : k * k + m * k].reshape(*batch, k, m)
        bias = genes[..., k * k + m * k :]
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
    neurons (:func:`mbn.control.mbn.make_mbn_controller`)."""
    return make_mbn_controller(
        program_neurons=range(programs),
        dt=dt,
        substeps=im_substeps,
        pm_substeps=pm_substeps,
        motor=motor,
    )


def _shared(tree: Any, dtype: Any) -> Shared:
    """A network every robot of the batch shares (:class:`mbn.world.rollout.Shared`), in
    ``dtype``."""
    return Shared(jax.tree.map(lambda a: jnp.asarray(a).astype(dtype), tree))


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
    im_b = _shared(im, dtype)
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
    fr, fl = tile_fitness(ar), tile_fitness(al)
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


#: Camera inputs of the program module: a one-colour tile in view, a two-colour tile, nothing.
_ONE, _TWO, _NONE = (1.0, 0.0), (0.0, 1.0), (0.0, 0.0)


#: Labels of the memory reward's episodes: scored as a right-follower, a left-follower, or by the
#: better of the two (rest).
RIGHT, LEFT, REST = 0, 1, 2


class MemoryEpisode(NamedTuple):
    """One episode of the :class:`MemoryReward`.

    Attributes:
        kind: the crossroad kind (``"LS"``, ...).
        tile: colours of the tile in its south arm (1 or 2), or None.
        sequence: the camera sequence shown to the PM first (:meth:`MemoryReward.sequences`).
        label: :data:`RIGHT`, :data:`LEFT` or :data:`REST`.
        approach: how the robot enters the crossroad (``"south"``, ``"west"``, ``"east"``).
    """

    kind: str
    tile: int | None
    sequence: str
    label: int
    approach: str


@dataclass(frozen=True)
class MemoryReward:
    """The PM reward with switching and memory episodes (``docs/experiments.md``).

    The paper's two trials (one-colour tiles scored as a right-follower, two-colour tiles as a
    left-follower) start the PM from rest: they never ask it to *switch*, nor to hold a program
    longer than an episode. Here, on the crossroads ``kinds`` (those where the two rules part), each
    rule has three episodes:

    * ``plain``: the paper's, the rule's tile one cell north of the start, PM from rest;
    * ``switch``: the same, but the PM was first shown the *other* tile for ``see`` seconds and then
      nothing for ``hold`` seconds;
    * ``memory``: no tile; the PM was shown the other tile (``see``), nothing (``gap``), the rule's
      tile (``see``) and nothing for ``memory`` seconds;

    and on ``rest_kinds`` a PM from rest in a crossroad without tiles is scored by the better of
    the two rules (it must drive as some wall follower). The episodes without a tile (memory and
    rest) are also run from each of ``approaches`` other than ``"south"``: the crossroad entered
    round a corner (:func:`mbn.world.mazes.builtin.crossroad`), where a program that is nearly but
    not quite a wall follower's gives itself away. Before an episode the PM alone is
    integrated through its camera sequence (standing for tiles seen earlier). The reward keeps the
    paper's product: ``(R + Z) (L + Z)`` with R (L) the summed branch fitness of the right (left)
    episodes and Z = ``rest_weight`` x the rest episodes' sum, each clipped at 0.

    ``fidelity`` > 0 makes each episode's score its branch fitness minus ``fidelity`` x the mean
    motor mismatch (:func:`mbn.control.ctrnn.shadowed`) between the MBN and the network whose rule
    the episode rewards (RF or LF, riding along on the same sensor readings; rest episodes take the
    better of the two). The branch fitness alone cannot tell a program from a slightly shifted one
    that happens to score higher on the crossroads and stalls elsewhere; the mismatch is least for
    the program itself (``docs/experiments.md``). It needs the reference networks
    (:func:`pm_memory_fitness` ``references``).
    """

    kinds: tuple[str, ...] = ("LS", "LR", "SR", "LSR")
    rest_kinds: tuple[str, ...] = ("L", "R", "LSR")
    rest_weight: float = 0.5
    see: float = 1.5
    hold: float = 30.0
    gap: float = 20.0
    memory: float = 50.0
    approaches: tuple[str, ...] = ("south",)
    fidelity: float = 0.0

    def __post_init__(self) -> None:
        from mbn.world.mazes.builtin import check_approaches

        check_approaches(self.approaches)
        if not self.fidelity >= 0:
            raise MbnInputError(f"fidelity must be >= 0, got {self.fidelity!r}")

    def sequences(self) -> dict[str, list[tuple[tuple[float, float], float]]]:
        """Camera sequences ``[(input, seconds), ...]`` fed to the PM before each kind of
        episode."""
        return {
            "rest": [],
            "after_one": [(_ONE, self.see), (_NONE, self.hold)],
            "after_two": [(_TWO, self.see), (_NONE, self.hold)],
            "memory_one": [
                (_TWO, self.see),
                (_NONE, self.gap),
                (_ONE, self.see),
                (_NONE, self.memory),
            ],
            "memory_two": [
                (_ONE, self.see),
                (_NONE, self.gap),
                (_TWO, self.see),
                (_NONE, self.memory),
            ],
        }

    def episodes(self) -> list[MemoryEpisode]:
        """The reward's episodes (:class:`MemoryEpisode`)."""
        from mbn.world.mazes.builtin import CROSSROAD_KINDS

        out: list[MemoryEpisode] = []
        for a in self.approaches:
            south = a == "south"
            for k in CROSSROAD_KINDS:
                if k in self.kinds:
                    if south:  # a tile lies in the south arm
                        out += [
                            MemoryEpisode(k, 1, "rest", RIGHT, a),
                            MemoryEpisode(k, 2, "rest", LEFT, a),
                            MemoryEpisode(k, 1, "after_two", RIGHT, a),
                            MemoryEpisode(k, 2, "after_one", LEFT, a),
                        ]
                    out += [
                        MemoryEpisode(k, None, "memory_one", RIGHT, a),
                        MemoryEpisode(k, None, "memory_two", LEFT, a),
                    ]
                if k in self.rest_kinds:
                    out.append(MemoryEpisode(k, None, "rest", REST, a))
        return out


def camera_inputs(
    sequence: Sequence[tuple[tuple[float, ...], float]], dt: float = 0.1
) -> np.ndarray:
    """A camera sequence ``[(input, seconds), ...]`` as one input row per robot step (as many
    columns as the inputs have: one per tile kind)."""
    width = len(sequence[0][0]) if sequence else 2
    rows = [x for x, secs in sequence for _ in range(round(secs / dt))]
    return np.array(rows, np.float32).reshape(-1, width)


def prime(pm: CTRNN, inputs: list[np.ndarray], dt: float = 0.1, substeps: int = 4) -> Array:
    """Program-module states after each camera input sequence, from rest: ``(P, S, n)`` for a
    batch of ``P`` networks and ``S`` sequences (``inputs[s]``: ``(steps, m)`` for ``m`` inputs,
    one row per robot step of ``dt`` seconds, integrated in ``substeps`` Euler steps as the MBN
    controller does)."""
    p, n = pm.W.shape[0], pm.W.shape[-1]
    dtype = pm.W.dtype
    h = dt / substeps
    outs = []
    for seq in inputs:
        y = jnp.zeros((p, n), dtype)
        if len(seq):

            def step(y: Array, x: Array) -> tuple[Array, None]:
                for _ in range(substeps):
                    y = euler_step(pm, y, jnp.broadcast_to(x, (p, x.shape[-1])), h)
                return y, None

            y, _ = jax.lax.scan(step, y, jnp.asarray(seq, dtype))
        outs.append(y)
    return jnp.stack(outs, 1)


def pm_program_fitness(
    genome: PMGenome,
    programs: tuple[tuple[float, ...], tuple[float, ...]],
    *,
    reward: MemoryReward | None = None,
    dt: float = 0.1,
    substeps: int = 4,
    see: float | None = None,
    switch: float = 0.3,
) -> Callable[[Array], Array]:
    """A jitted map from a PM population to how well each latches the interpreter's programs,
    without the robot: minus the mean squared difference between the program the PM sends and
    the program of the last tile it was shown, over the reward's switching and memory sequences
    (:meth:`MemoryReward.sequences`: after a one-colour tile, after a two-colour tile, and each
    tile after the other; each tile in view for ``see`` seconds, default the reward's): every
    robot step without input once a tile has been shown, and every step with a tile in view
    once it has been seen for ``switch`` seconds (the program must change while the tile is in
    view, which the camera may show only briefly). ``programs``: RF's and LF's (one-colour
    tile: the first). The ``pm`` stage's default reward (``docs/reproduce.md``, the program
    reward); 0 is its maximum."""
    reward = reward or MemoryReward()
    if see is not None:
        reward = dataclasses.replace(reward, see=see)
    right, left = (np.asarray(p, np.float64) for p in programs)
    k = genome.programs
    if right.shape != (k,) or left.shape != (k,):
        raise MbnInputError(f"programs must have {k} values each, got {len(right)} and {len(left)}")
    seqs = [v for name, v in sorted(reward.sequences().items()) if name != "rest"]
    return code_fitness(
        genome, seqs, {_ONE: right, _TWO: left}, dt=dt, substeps=substeps, switch=switch
    )


def tile_sequences(
    kinds: int, reward: MemoryReward | None = None
) -> list[list[tuple[tuple[float, ...], float]]]:
    """Camera sequences for ``kinds`` tile kinds (inputs one-hot, one per kind), as the memory
    reward's for two: each tile alone and then held (``see``, then ``hold`` seconds), and each
    tile after each other one (``see``, ``gap``, ``see``, ``memory``)."""
    reward = reward or MemoryReward()
    eye = [tuple(float(i == t) for i in range(kinds)) for t in range(kinds)]
    none = (0.0,) * kinds
    out = [[(eye[t], reward.see), (none, reward.hold)] for t in range(kinds)]
    for a in range(kinds):
        for b in range(kinds):
            if a != b:
                out.append(
                    [
                        (eye[a], reward.see),
                        (none, reward.gap),
                        (eye[b], reward.see),
                        (none, reward.memory),
                    ]
                )
    return out


def code_fitness(
    genome: PMGenome,
    sequences: Sequence[Sequence[tuple[tuple[float, ...], float]]],
    target_of: Mapping[tuple[float, ...], np.ndarray],
    *,
    dt: float = 0.1,
    substeps: int = 4,
    switch: float = 0.3,
) -> Callable[[Array], Array]:
    """A jitted map from a PM population to how well each sends the code of the last tile it
    was shown (``target_of[input]``, ``(programs,)``), without the robot: minus the mean squared
    difference over ``sequences`` of ``(input, seconds)`` (an input of zeros: no tile in view),
    scored every step without input once a tile has been shown, and every step with a tile in
    view once it has been seen for ``switch`` seconds (:func:`pm_program_fitness`)."""
    k, m = genome.programs, genome.inputs
    none = (0.0,) * m
    inputs, targets, weights = [], [], []
    for seq in sequences:
        rows, goal, w = [], [], []
        last = None
        for x, secs in seq:
            if len(x) != m:
                raise MbnInputError(f"a camera input of {len(x)} values for a PM of {m} inputs")
            n = round(secs / dt)
            rows += [x] * n
            if tuple(x) != none:
                last = np.asarray(target_of[tuple(x)], np.float64)
                if last.shape != (k,):
                    raise MbnInputError(f"codes must have {k} values each, got {last.shape}")
                # in view: scored once it has been seen for ``switch`` seconds
                wait = min(round(switch / dt), n)
                w += [0.0] * wait + [1.0] * (n - wait)
            else:  # no input: scored once a tile has been shown
                w += [1.0 if last is not None else 0.0] * n
            goal += [last if last is not None else np.zeros(k)] * n
        inputs.append(np.asarray(rows, np.float32).reshape(-1, m))
        targets.append(np.asarray(goal, np.float32))
        weights.append(np.asarray(w, np.float32))
    length = max(len(r) for r in inputs)

    def pad(a: np.ndarray) -> np.ndarray:
        return np.concatenate([a, np.zeros((length - len(a), *a.shape[1:]), a.dtype)])

    x_all = np.stack([pad(a) for a in inputs], 1)  # (T, S, m)
    t_all = np.stack([pad(a) for a in targets], 1)  # (T, S, k)
    w_all = np.stack([pad(a) for a in weights], 1)  # (T, S)
    total = float(w_all.sum())
    h = dt / substeps

    @jax.jit
    def fitness(population: Array) -> Array:
        p, dtype = population.shape[0], population.dtype
        net = genome.network(population)
        # (P, S, n) networks and states: each sequence runs beside the others
        s = x_all.shape[1]
        nets = jax.tree.map(lambda a: jnp.repeat(a[:, None], s, 1), net)

        def step(y: Array, row: tuple[Array, Array, Array]) -> tuple[Array, Array]:
            x, goal, w = row
            for _ in range(substeps):
                y = euler_step(nets, y, jnp.broadcast_to(x, (p, s, m)), h)
            rates = firing_rate(nets, y)[..., :k]
            err = jnp.sum((rates - goal) ** 2, -1) * w  # (P, S)
            return y, err.sum(-1)

        y0 = jnp.zeros((p, s, net.W.shape[-1]), dtype)
        rows = (jnp.asarray(x_all, dtype), jnp.asarray(t_all, dtype), jnp.asarray(w_all, dtype))
        _, err = jax.lax.scan(step, y0, rows)
        return -err.sum(0) / (total * k)

    return fitness


class Latch(NamedTuple):
    """The state a program module settles in after a tile (:func:`latch_after_tile`).

    Attributes:
        potentials: the PM's membrane potentials ``(n,)`` (float64).
        program: the firing rates of its program neurons there.
        seconds: seconds without input after the tile until it was taken as settled.
    """

    potentials: np.ndarray
    program: np.ndarray
    seconds: float


def latch_after_tile(
    pm: CTRNN,
    colors: int,
    program_neurons: tuple[int, ...] | range,
    *,
    see: float = 1.5,
    dt: float = 0.1,
    substeps: int = 4,
    settle: float = 30.0,
    check: float = 10.0,
    tol: float = 1e-4,
    max_seconds: float = 600.0,
) -> Latch | None:
    """The state ``pm`` (one network) latches after a tile of ``colors`` colours: from rest, the
    camera input of that tile for ``see`` seconds (the reward's :attr:`MemoryReward.see`), then
    no input for ``settle`` seconds, integrated as the MBN does (:func:`prime`: ``substeps``
    Euler steps per robot step of ``dt``). It is settled when ``check`` more seconds without
    input move no program value by more than ``tol`` and no potential by more than
    ``100 tol``; else ``settle`` doubles, up to ``max_seconds``. Returns None when it never
    settles (a PM that oscillates has no state to start from)."""
    if pm.W.ndim != 2:
        raise MbnInputError("latch_after_tile takes one network")
    kinds = pm.WE.shape[-1]
    if not (isinstance(colors, int) and 1 <= colors <= kinds):
        raise MbnInputError(f"colors must be 1 to {kinds} (the PM's tile kinds), got {colors!r}")
    neurons = list(program_neurons)
    tile = tuple(float(i == colors - 1) for i in range(kinds))
    none = (0.0,) * kinds
    one = jax.tree.map(lambda a: jnp.asarray(a)[None], pm)
    wait = settle
    while wait <= max_seconds:
        seqs = [[(tile, see), (none, wait)], [(tile, see), (none, wait + check)]]
        y = np.asarray(prime(one, [camera_inputs(q, dt) for q in seqs], dt, substeps)[0])
        rates = np.asarray(firing_rate(pm, jnp.asarray(y, pm.W.dtype)))[:, neurons]
        if np.max(np.abs(rates[1] - rates[0])) <= tol and np.max(np.abs(y[1] - y[0])) <= 100 * tol:
            return Latch(y[1].astype(np.float64), rates[1].astype(np.float64), wait + check)
        wait *= 2
    return None


def start_mismatch(
    pm: CTRNN,
    im: CTRNN,
    potentials: np.ndarray,
    references: tuple[CTRNN, CTRNN],
    program_neurons: tuple[int, ...] | range,
    *,
    approaches: tuple[str, ...] = ("south", "west", "east"),
    im_substeps: int = 20,
    pm_substeps: int = 4,
    camera: CameraConfig | None = None,
) -> tuple[float, float]:
    """How the MBN drives before any tile when its PM starts at ``potentials``: its mean motor
    mismatch (:func:`mbn.control.ctrnn.shadowed`) with the right- and the left-follower of
    ``references`` riding along, over the seven crossroads without tiles entered from each of
    ``approaches`` (one episode each from the mark, :data:`~mbn.experiments.crossroads.
    EPISODE_SECONDS`). Returns ``(right, left)``: the smaller names the rule it drives by."""
    from mbn.control.ctrnn import CTRNNState, ShadowedState, shadowed
    from mbn.world.engine import compile_mazes
    from mbn.world.mazes.builtin import CROSSROAD_KINDS, crossroad
    from mbn.world.rollout import junction_arrays

    task = CrossroadTask()
    mazes = [crossroad(kind, approach=a) for a in approaches for kind in CROSSROAD_KINDS]
    n = len(mazes)
    dtype = im.W.dtype
    world = compile_mazes(mazes)
    junctions = junction_arrays(mazes, world)
    config = task.rollout_config(camera=camera or CameraConfig())
    controller = shadowed(
        make_mbn_controller(
            program_neurons=tuple(program_neurons),
            dt=task.dt,
            substeps=im_substeps,
            pm_substeps=pm_substeps,
        ),
        dt=task.dt,
        substeps=im_substeps,
    )
    refs = jax.tree.map(lambda a, b: jnp.stack([jnp.asarray(a), jnp.asarray(b)]), *references)
    state = ShadowedState(
        MBNState(
            _shared(pm, dtype),
            jnp.broadcast_to(jnp.asarray(potentials, dtype), (n, pm.num_neurons)),
            _shared(im, dtype),
            jnp.zeros((n, im.num_neurons), dtype),
        ),
        CTRNNState(_shared(refs, dtype), jnp.zeros((n, 2, refs.W.shape[-1]), dtype)),
        jnp.zeros((n, 2), dtype),
    )
    poses = jnp.asarray(np.stack([m.starts[0] for m in mazes]), dtype)
    result = jax.jit(
        lambda st, p: rollout(world, controller, st, p, jnp.arange(n), config, junctions=junctions)
    )(state, poses)
    mismatch = np.asarray(result.controller_state.mismatch, np.float64) / config.steps
    right, left = mismatch.mean(0)
    return float(right), float(left)


def pm_memory_fitness(
    genome: PMGenome,
    im: CTRNN,
    *,
    reward: MemoryReward | None = None,
    variants: int = 2,
    seed: int = 0,
    im_substeps: int = 20,
    pm_substeps: int = 4,
    camera: CameraConfig | None = None,
    seconds: float = 30.0,
    references: tuple[CTRNN, CTRNN] | None = None,
) -> Callable[[Array], Array]:
    """A jitted map from a PM population to the :class:`MemoryReward` (``variants`` starts per
    episode: the mark and jittered ones, seeded by ``seed``). ``references``: the right- and the
    left-follower the interpreter's programs stand for (needed when ``reward.fidelity`` > 0; they
    run with ``im_substeps`` too)."""
    from mbn.control.ctrnn import CTRNNState, ShadowedState, shadowed
    from mbn.experiments.crossroads import ARM_VECTORS, episode_fitness, rule_arm
    from mbn.experiments.starts import jittered_starts
    from mbn.world.engine import compile_mazes
    from mbn.world.mazes.builtin import crossroad
    from mbn.world.rollout import junction_arrays

    reward = reward or MemoryReward()
    camera = camera or CameraConfig()
    if reward.fidelity > 0 and references is None:
        raise MbnInputError(
            "MemoryReward.fidelity > 0 needs the reference networks: references=(rf, lf)"
        )
    specs = reward.episodes()
    if not specs:
        raise MbnInputError("the PM reward has no episodes (kinds and rest_kinds are empty)")
    task = CrossroadTask(seconds=seconds, variants=variants, seed=seed)
    dt = task.dt
    mazes = [crossroad(s.kind, tile=s.tile, approach=s.approach) for s in specs]
    base = np.stack([m.starts[0] for m in mazes])
    poses = jittered_starts(base, variants, task.jitter, seed)
    index = np.tile(np.arange(len(mazes)), variants)
    e = len(poses)
    centre = np.array([[m.bounds[1] / 2, m.bounds[3] / 2] for m in mazes])[index]
    target = {
        rule: np.array([ARM_VECTORS[rule_arm(s.kind, rule)] for s in specs])[index]
        for rule in ("right", "left")
    }
    label = jnp.asarray(np.array([s.label for s in specs])[index])
    names = sorted(reward.sequences())
    which = np.array([names.index(s.sequence) for s in specs])[index]
    inputs = [camera_inputs(reward.sequences()[n], dt) for n in names]
    world = compile_mazes(mazes)
    junctions = junction_arrays(mazes, world)
    config = task.rollout_config(camera=camera)
    controller: Callable[[Any, Any], tuple[Any, tuple[Array, Array]]] = mbn_controller(
        programs=genome.programs, dt=dt, im_substeps=im_substeps, pm_substeps=pm_substeps
    )
    k = genome.programs
    # The references ride along only when their mismatch is scored.
    shadow = references is not None and reward.fidelity > 0
    if shadow:
        assert references is not None
        controller = shadowed(controller, dt=dt, substeps=im_substeps)
        refs = jax.tree.map(lambda a, b: jnp.stack([jnp.asarray(a), jnp.asarray(b)]), *references)

    def arrays(rule: str, p: int) -> TaskArrays:
        return TaskArrays(
            mazes=mazes,
            world=world,
            junctions=junctions,
            poses=np.tile(poses, (p, 1)),
            maze_index=np.tile(index, p),
            target=np.tile(target[rule], (p, 1)),
            centre=np.tile(centre, (p, 1)),
            cell=float(mazes[0].cell or 1.2),
            arm_length=3 * float(mazes[0].cell or 1.2),
        )

    @jax.jit
    def fitness(population: Array) -> Array:
        p, dtype = population.shape[0], population.dtype
        n = p * e
        y0 = prime(genome.network(population), inputs, dt, pm_substeps)[:, jnp.asarray(which)]
        im_b = _shared(im, dtype)
        state: Any = MBNState(
            genome.network(jnp.repeat(population, e, 0)),
            y0.reshape(n, k),
            im_b,
            jnp.zeros((n, im.num_neurons), dtype),
        )
        if shadow:
            r_net = _shared(refs, dtype)
            r_y = jnp.zeros((n, 2, refs.W.shape[-1]), dtype)
            state = ShadowedState(state, CTRNNState(r_net, r_y), jnp.zeros((n, 2), dtype))
        result = rollout(
            world,
            controller,
            state,
            jnp.asarray(np.tile(poses, (p, 1)), dtype),
            jnp.asarray(np.tile(index, p)),
            config,
            junctions=junctions,
        )
        stats = result.stats
        f_right = episode_fitness(stats, arrays("right", p), task).reshape(p, e)
        f_left = episode_fitness(stats, arrays("left", p), task).reshape(p, e)
        if shadow:
            mismatch = (result.controller_state.mismatch / config.steps).reshape(p, e, 2)
            f_right = f_right - reward.fidelity * mismatch[..., 0]
            f_left = f_left - reward.fidelity * mismatch[..., 1]
        r = jnp.clip(jnp.where(label == 0, f_right, 0.0).sum(-1), 0.0, None)
        left = jnp.clip(jnp.where(label == 1, f_left, 0.0).sum(-1), 0.0, None)
        best = jnp.maximum(f_right, f_left)
        z = reward.rest_weight * jnp.clip(jnp.where(label == 2, best, 0.0).sum(-1), 0.0, None)
        return (r + z) * (left + z)

    return fitness


#: A PM genome driving the robot in mazes starts in the state it reaches after a one-colour tile
#: shown for this long (s) and then this long without input (:func:`pm_maze_fitness`), as the
#: MBN it makes starts latched (:func:`latch_after_tile`).
MAZE_START_SEE, MAZE_START_SETTLE = 1.5, 40.0


def pm_maze_fitness(
    template: Any, genome: PMGenome, task: Any, arrays: TaskArrays | None = None
) -> Callable[..., Array]:
    """A jitted map from a population of program modules ``(P, genome.size)`` to their fitness
    driving the robot in a maze task (:class:`~mbn.experiments.maze_task.MazeTask` of rule
    ``"tiles"``: the rule in force is the last tile's), summed over its episodes
    (:func:`~mbn.experiments.maze_task.maze_episode_fitness`): each genome's PM in the MBN
    ``template`` (an :class:`~mbn.controllers.MBNControllerSpec`: its interpreter, programs,
    readout, camera and substeps, run as the controller file runs, under the task's noise),
    started in the state it reaches after a one-colour tile (:data:`MAZE_START_SEE` s in view,
    then :data:`MAZE_START_SETTLE` s without input: the MBN starts latched after tile 1).
    Arguments after the population (a DE group's owners) are ignored."""
    from mbn.controllers import make_controller
    from mbn.experiments.maze_task import MazeTask, maze_episode_fitness

    if not isinstance(task, MazeTask) or task.rule != "tiles":
        raise MbnInputError("pm_maze_fitness needs a maze task of rule 'tiles'")
    noise = task.noise if task.noise.enabled else None
    loaded = make_controller(template, where="template", check_stability=False, noise=noise)
    if loaded.dt != task.dt or loaded.sensors != task.sensors:
        raise MbnInputError("template: its robot step and sensors must be the maze task's")
    pm = template.program_module
    if (pm.num_neurons, pm.num_inputs) != (genome.programs, genome.inputs):
        raise MbnInputError(
            f"template: a program module of {pm.num_neurons} neurons and {pm.num_inputs} "
            f"inputs, the genome's has {genome.programs} and {genome.inputs}"
        )
    arrays = arrays or task.arrays()
    e = arrays.episodes
    shared = loaded.initial_state(1)
    control = loaded.controller
    config = task.rollout_config(camera=loaded.camera)
    pm_substeps = template.pm_substeps
    tile = tuple(float(i == 0) for i in range(genome.inputs))
    start = camera_inputs(
        [(tile, MAZE_START_SEE), ((0.0,) * genome.inputs, MAZE_START_SETTLE)], task.dt
    )
    poses, index = np.asarray(arrays.poses), np.asarray(arrays.maze_index, np.int32)

    @jax.jit
    def run(population: Array) -> Array:
        p, dtype = population.shape[0], population.dtype
        nets = genome.network(population)
        y0 = prime(nets, [start], task.dt, pm_substeps)[:, 0]
        state = shared._replace(
            pm=genome.network(jnp.repeat(population, e, 0)),
            pm_y=jnp.repeat(y0, e, 0).astype(dtype),
            im_y=jnp.zeros((p * e, shared.im_y.shape[-1]), dtype),
        )
        stats = rollout(
            arrays.world,
            control,
            state,
            jnp.asarray(np.tile(poses, (p, 1)), dtype),
            jnp.asarray(np.tile(index, p)),
            config,
            junctions=arrays.junctions,
            key=task.rollout_key,
        ).stats
        return maze_episode_fitness(stats, task).reshape(p, e).sum(-1)

    def fitness(population: Array, *_per_genome: Array) -> Array:
        return run(jnp.asarray(population))

    return fitness


def memory_reward_maximum(reward: MemoryReward, variants: int) -> float:
    """The largest value of the :class:`MemoryReward` (every episode scoring its maximum,
    :data:`~mbn.experiments.crossroads.EPISODE_FITNESS_MAX`)."""
    specs = reward.episodes()
    per = EPISODE_FITNESS_MAX * variants
    r = per * sum(1 for s in specs if s.label == RIGHT)
    left = per * sum(1 for s in specs if s.label == LEFT)
    z = reward.rest_weight * per * sum(1 for s in specs if s.label == REST)
    return (r + z) * (left + z)
