"""Differential Evolution, DE/best/1/bin, as pure ask/tell functions over explicit state and keys.

The paper (Montone, Donnarumma & Prevete 2011, section 3.1) evolves the CTRNN controllers with
DE/best/1/bin, population 18, step size ``F = 0.85``, crossover rate ``CR = 0.2`` and initial
weights uniform in ``[-100, 100]``; those are the defaults of :class:`DEConfig`.

One generation, for every target ``i`` of the population ``x`` (shape ``(popsize, num_dims)``):

1. draw partners ``r1 != r2``, both ``!= i``, uniformly (:func:`draw_partners`);
2. mutant ``v_i = x_best + F * (x_r1 - x_r2)`` where ``x_best`` is the best member so far;
3. binomial crossover: gene ``j`` of the trial ``u_i`` is ``v_ij`` with probability ``CR`` and
   ``x_ij`` otherwise, except that one gene ``j_rand(i)``, drawn uniformly, always comes from the
   mutant, so every trial differs from its target (:func:`draw_cross_mask`);
4. the bounds policy puts the trial back into ``[lower, upper]`` (:func:`apply_bounds`:
   ``"clip"``, ``"reflect"`` or ``"resample"``, the last one with uniform random draws);
5. after the whole trial population is evaluated, each trial replaces its target when its fitness
   is better or equal (greedy one-to-one selection, :func:`tell`).

The update is *deferred* (generation-based, like ``scipy``'s ``updating="deferred"``): all
``popsize`` trials of a generation are built from the same population and the same best, so a
whole population can be evaluated in one batched, jitted call. :func:`ask` returns the trials,
:func:`tell` takes their fitness.

Typical use::

    config = DEConfig(num_dims=10, init_low=-5.0, init_high=5.0, lower=-5.0, upper=5.0)
    k_init, k_run = jax.random.split(jax.random.key(0))
    state = init(k_init, config)
    state = initialize_fitness(state, fitness_fn(state.population), config)
    for key in jax.random.split(k_run, 100):
        trials = ask(key, state, config)
        state = tell(state, trials, fitness_fn(trials), config)

or, for a jittable ``fitness_fn``, ``state, history = minimize(fitness_fn, key, config, 100)``.

Floating point: arrays are float64 when ``jax_enable_x64`` is on and float32 otherwise (JAX's
default); :func:`init` and :func:`from_population` pick the type at call time. Every function
here is a pure function of immutable data and jit-compiles with ``config`` static (the public
array functions are already wrapped in :func:`jax.jit` with ``static_argnames="config"``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence
from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from mbn.errors import MbnInputError

BoundsPolicy = Literal["clip", "reflect", "resample"]
BOUNDS_POLICIES: tuple[BoundsPolicy, ...] = ("clip", "reflect", "resample")

#: Smallest population accepted. DE/best/1 needs the target plus two distinct partners (3), and
#: with exactly 3 the partners are forced; 4 leaves the partner draw some randomness. (scipy asks
#: for at least 5 members.)
MIN_POPSIZE = 4

# Purposes for jax.random.fold_in: each random draw gets its own, named stream.
_PURPOSE_PARTNER_R1 = 0
_PURPOSE_PARTNER_R2 = 1
_PURPOSE_CROSSOVER = 2
_PURPOSE_J_RAND = 3
_PURPOSE_INIT = 4
_PURPOSE_GENERATIONS = 5
_PURPOSE_RESAMPLE = 6

__all__ = [
    "BOUNDS_POLICIES",
    "MIN_POPSIZE",
    "BoundsPolicy",
    "DEConfig",
    "DEState",
    "apply_bounds",
    "ask",
    "draw_cross_mask",
    "draw_partners",
    "from_population",
    "init",
    "initialize_fitness",
    "minimize",
    "mutate_crossover",
    "tell",
]


# ---------------------------------------------------------------------------------------------
# Configuration
# ---------------------------------------------------------------------------------------------


def _is_int(value: object) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool | np.bool_)


def _real(value: object, name: str) -> float:
    """``value`` as a Python float, or MbnInputError naming ``name``."""
    if isinstance(value, bool | np.bool_):
        raise MbnInputError(f"{name}: must be a number, got {value!r}")
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise MbnInputError(f"{name}: must be a number, got {value!r}") from None
    if arr.shape != ():
        raise MbnInputError(f"{name}: must be a scalar, got shape {arr.shape}")
    return float(arr)


def _per_gene(
    value: float | Sequence[float] | ArrayLike, name: str, num_dims: int, hint: str = ""
) -> float | tuple[float, ...]:
    """Normalise to a finite float or a tuple of ``num_dims`` finite floats."""
    if value is None or isinstance(value, bool | np.bool_):
        raise MbnInputError(f"{name}: must be a number or a sequence of numbers, got {value!r}")
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise MbnInputError(
            f"{name}: must be a number or a sequence of numbers, got {value!r}"
        ) from None
    if arr.ndim > 1 or (arr.ndim == 1 and arr.shape[0] != num_dims):
        raise MbnInputError(
            f"{name}: must be a scalar or have shape ({num_dims},) (num_dims), got shape "
            f"{arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise MbnInputError(f"{name}: must be finite{hint}, got {value!r}")
    if arr.ndim == 0:
        return float(arr)
    return tuple(float(v) for v in arr)


def _bound(
    value: float | Sequence[float] | ArrayLike | None, name: str, num_dims: int
) -> float | tuple[float, ...] | None:
    """Normalise a bound to None, a finite float or a tuple of ``num_dims`` finite floats."""
    if value is None:
        return None
    return _per_gene(value, name, num_dims, " (use None for no bound)")


def _genes(value: float | tuple[float, ...], num_dims: int) -> np.ndarray:
    """A scalar or per-gene setting as a float64 array of shape ``(num_dims,)``."""
    return np.broadcast_to(np.asarray(value, dtype=np.float64), (num_dims,))


def _check_init_inside_bounds(
    init_low: float | tuple[float, ...],
    init_high: float | tuple[float, ...],
    lower: float | tuple[float, ...] | None,
    upper: float | tuple[float, ...] | None,
    num_dims: int,
) -> None:
    """MbnInputError unless ``lower <= init_low`` and ``init_high <= upper`` for every gene."""
    lo_init, hi_init = _genes(init_low, num_dims), _genes(init_high, num_dims)
    lo = _genes(-math.inf if lower is None else lower, num_dims)
    hi = _genes(math.inf if upper is None else upper, num_dims)
    for name, bad in (("init_low", lo_init < lo), ("init_high", hi_init > hi)):
        if np.any(bad):
            j = int(np.flatnonzero(bad)[0])
            raise MbnInputError(
                f"{name}: the initial range [init_low, init_high] must lie inside the bounds "
                f"[lower, upper] for every gene, got [init_low, init_high] = "
                f"[{lo_init[j]}, {hi_init[j]}] outside [lower, upper] = [{lo[j]}, {hi[j]}] at "
                f"gene {j}"
            )


@dataclasses.dataclass(frozen=True, kw_only=True)
class DEConfig:
    """Static settings of DE/best/1/bin. Defaults are the paper's (section 3.1).

    The config is a frozen, hashable dataclass (per-gene bounds are stored as tuples), so it can be
    a static argument of :func:`jax.jit`. Arguments are validated on construction; bad values
    raise :class:`~mbn.errors.MbnInputError` naming the parameter.

    Attributes:
        num_dims: genes per genome, ``>= 1``.
        popsize: population size, ``>= 4`` (see :data:`MIN_POPSIZE`). Paper: 18.
        F: differential weight (the paper's "step-size"), in ``(0, 2]``. Paper: 0.85.
        CR: binomial crossover rate, in ``[0, 1]``. Paper: 0.2.
        init_low: the initial population is uniform in ``[init_low, init_high]``; a finite float
            or ``num_dims`` finite floats (stored as a tuple), like the bounds. Paper: -100.
        init_high: see ``init_low``; ``init_low < init_high`` gene by gene. Paper: 100. When
            bounds are set, the initial range must lie inside them gene by gene (``lower <=
            init_low`` and ``init_high <= upper``), else :class:`~mbn.errors.MbnInputError`: an
            initial range wider than the box would be bounded by the policy, e.g. the default
            ``[-100, 100]`` clipped into ``[-1, 1]`` puts nearly every gene on a bound, where DE
            stalls. So with bounds, set ``init_low``/``init_high`` too.
        lower: lower bound of the genes: None (unbounded), a finite float, or ``num_dims`` finite
            floats (a sequence or array, stored as a tuple). The paper states no bounds.
        upper: upper bound, like ``lower``; ``lower < upper`` gene by gene where both are given.
        bounds_policy: how trial genes outside ``[lower, upper]`` are brought back; ``"clip"``
            (onto the violated bound, the default), ``"reflect"`` (mirrored about it, then
            clipped) or ``"resample"`` (replaced by a uniform random value in ``[lower, upper]``,
            as scipy does; needs both ``lower`` and ``upper``, or no bounds at all). See
            :func:`apply_bounds`. ``"clip"`` is the default because it is deterministic (no
            random draws in the bounds step) and keeps a gene that is pushed out at the bound,
            the value the search pushed towards, rather than throwing it to a random place.
        maximize: False: smaller fitness is better (DE's usual convention); True: larger fitness
            is better (robot fitness).
    """

    num_dims: int
    popsize: int = 18  # section 3.1: population of 18 individuals
    F: float = 0.85  # section 3.1: "step-size" F = 0.85 (differential weight)
    CR: float = 0.2  # section 3.1: crossover CR = 0.2
    init_low: float | tuple[float, ...] = -100.0  # section 3.1: initial weights in [-100, 100]
    init_high: float | tuple[float, ...] = 100.0  # section 3.1: initial weights in [-100, 100]
    lower: float | tuple[float, ...] | None = None  # not in the paper: unbounded by default
    upper: float | tuple[float, ...] | None = None  # not in the paper: unbounded by default
    bounds_policy: BoundsPolicy = "clip"  # not in the paper (no bounds there); see above
    maximize: bool = False  # DE minimises; the paper maximises robot fitness (use True)

    def __post_init__(self) -> None:
        set_ = functools.partial(object.__setattr__, self)
        if not _is_int(self.num_dims) or self.num_dims < 1:
            raise MbnInputError(f"num_dims: must be an integer >= 1, got {self.num_dims!r}")
        set_("num_dims", int(self.num_dims))
        if not _is_int(self.popsize) or self.popsize < MIN_POPSIZE:
            raise MbnInputError(
                f"popsize: must be an integer >= {MIN_POPSIZE}, got {self.popsize!r}"
            )
        set_("popsize", int(self.popsize))
        F = _real(self.F, "F")
        if not 0.0 < F <= 2.0:
            raise MbnInputError(f"F: must be in (0, 2], got {F}")
        set_("F", F)
        CR = _real(self.CR, "CR")
        if not 0.0 <= CR <= 1.0:
            raise MbnInputError(f"CR: must be in [0, 1], got {CR}")
        set_("CR", CR)
        init_low = _per_gene(self.init_low, "init_low", self.num_dims)
        init_high = _per_gene(self.init_high, "init_high", self.num_dims)
        lo_init, hi_init = _genes(init_low, self.num_dims), _genes(init_high, self.num_dims)
        bad = np.flatnonzero(~(lo_init < hi_init))
        if bad.size:
            j = int(bad[0])
            raise MbnInputError(
                f"init_low: must be < init_high for every gene, got init_low={lo_init[j]}, "
                f"init_high={hi_init[j]} at gene {j}"
            )
        set_("init_low", init_low)
        set_("init_high", init_high)
        lower = _bound(self.lower, "lower", self.num_dims)
        upper = _bound(self.upper, "upper", self.num_dims)
        if lower is not None and upper is not None:
            lo, hi = _genes(lower, self.num_dims), _genes(upper, self.num_dims)
            bad = np.flatnonzero(~(lo < hi))
            if bad.size:
                j = int(bad[0])
                raise MbnInputError(
                    f"lower: must be < upper for every gene, got lower={lo[j]} >= upper={hi[j]} "
                    f"at gene {j}"
                )
        set_("lower", lower)
        set_("upper", upper)
        _check_init_inside_bounds(init_low, init_high, lower, upper, self.num_dims)
        if self.bounds_policy not in BOUNDS_POLICIES:
            raise MbnInputError(
                f"bounds_policy: expected one of {BOUNDS_POLICIES}, got {self.bounds_policy!r}"
            )
        if self.bounds_policy == "resample" and (lower is None) != (upper is None):
            raise MbnInputError(
                "bounds_policy: 'resample' draws uniformly in [lower, upper] and needs both "
                f"bounds (or neither), got lower={lower!r}, upper={upper!r}"
            )
        if not isinstance(self.maximize, bool | np.bool_):
            raise MbnInputError(f"maximize: must be True or False, got {self.maximize!r}")
        set_("maximize", bool(self.maximize))

    @property
    def bounded(self) -> bool:
        """Whether any bound is set."""
        return self.lower is not None or self.upper is not None

    @property
    def worst_fitness(self) -> float:
        """The placeholder fitness of unevaluated members: +inf, or -inf when maximising."""
        return -math.inf if self.maximize else math.inf


def _float_dtype() -> jnp.dtype:
    """float64 when ``jax_enable_x64`` is on, else float32."""
    return jnp.dtype(jax.dtypes.canonicalize_dtype(jnp.float64))


def _bound_arrays(config: DEConfig, dtype: jnp.dtype) -> tuple[Array, Array]:
    """Lower and upper bounds, shape ``(num_dims,)``; ``-inf``/``+inf`` where there is none."""
    shape = (config.num_dims,)
    lo = -jnp.inf if config.lower is None else config.lower
    hi = jnp.inf if config.upper is None else config.upper
    return (
        jnp.broadcast_to(jnp.asarray(lo, dtype=dtype), shape),
        jnp.broadcast_to(jnp.asarray(hi, dtype=dtype), shape),
    )


# ---------------------------------------------------------------------------------------------
# State
# ---------------------------------------------------------------------------------------------


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class DEState:
    """The evolving state of DE (a pytree of arrays; float64 when ``jax_enable_x64`` is on).

    Attributes:
        population: genomes, shape ``(popsize, num_dims)``.
        fitness: fitness of each genome, shape ``(popsize,)``; ``+inf`` (``-inf`` when
            maximising) until :func:`initialize_fitness` is called. NaN values are kept as
            reported but rank below every number.
        best_genome: the best genome found so far, shape ``(num_dims,)``; the first member of the
            population until :func:`initialize_fitness` is called.
        best_fitness: its fitness, shape ``()``; never worsens in :func:`tell`.
        generation: completed generations (calls of :func:`tell`), shape ``()``, int32.
    """

    population: Array
    fitness: Array
    best_genome: Array
    best_fitness: Array
    generation: Array


def _check_shape(value: ArrayLike, name: str, shape: tuple[int, ...]) -> None:
    got = jnp.shape(value)
    if got != shape:
        raise MbnInputError(f"{name}: expected shape {shape}, got {got}")


def _check_state(state: DEState, config: DEConfig) -> None:
    _check_shape(state.population, "state.population", (config.popsize, config.num_dims))
    _check_shape(state.fitness, "state.fitness", (config.popsize,))


def _rank_key(fitness: Array, config: DEConfig) -> Array:
    """A key where smaller is better and NaN is worst (+inf)."""
    key = -fitness if config.maximize else fitness
    return jnp.where(jnp.isnan(key), jnp.inf, key)


def _better_or_equal(a: Array, b: Array, config: DEConfig) -> Array:
    """Whether fitness ``a`` is at least as good as ``b``: never when ``a`` is NaN, always when
    ``a`` is a number and ``b`` is NaN."""
    at_least = a >= b if config.maximize else a <= b
    return ~jnp.isnan(a) & (at_least | jnp.isnan(b))


@functools.partial(jax.jit, static_argnames="config")
def from_population(population: ArrayLike, config: DEConfig) -> DEState:
    """A fresh state from a given initial population (not yet evaluated).

    Args:
        population: initial genomes, shape ``(popsize, num_dims)``; brought into the bounds by
            the bounds policy (clipped under ``"resample"``, which would need random draws) and
            converted to float64 (x64 on) or float32.
        config: the DE settings.

    Returns:
        A state with ``fitness`` all worst (``+inf``, or ``-inf`` when maximising),
        ``best_genome = population[0]``, ``best_fitness`` worst and ``generation = 0``.
        Call :func:`initialize_fitness` with the fitness of ``state.population`` before
        :func:`ask`.

    Raises:
        MbnInputError: ``population`` has the wrong shape.
    """
    _check_shape(population, "population", (config.popsize, config.num_dims))
    dtype = _float_dtype()
    pop = jnp.asarray(population, dtype=dtype)
    if config.bounds_policy == "resample":
        lo, hi = _bound_arrays(config, dtype)
        pop = jnp.clip(pop, lo, hi)
    else:
        pop = apply_bounds(pop, config)
    worst = jnp.asarray(config.worst_fitness, dtype=dtype)
    return DEState(
        population=pop,
        fitness=jnp.full((config.popsize,), worst, dtype=dtype),
        best_genome=pop[0],
        best_fitness=worst,
        generation=jnp.zeros((), dtype=jnp.int32),
    )


@functools.partial(jax.jit, static_argnames="config")
def init(key: Array, config: DEConfig) -> DEState:
    """A fresh state with the population uniform in ``[init_low, init_high]``.

    The population is drawn uniformly in ``[config.init_low, config.init_high]`` (paper: [-100,
    100]; per gene when given per gene), which :class:`DEConfig` requires to lie inside
    ``[lower, upper]``. Arrays are float64 when ``jax_enable_x64`` is on, float32 otherwise
    (JAX's default, note that float32 has only ~7 significant digits).

    Args:
        key: a JAX PRNG key.
        config: the DE settings.

    Returns:
        The state as :func:`from_population` makes it: fitness unevaluated (worst), generation 0.
    """
    dtype = _float_dtype()
    population = jax.random.uniform(
        key,
        (config.popsize, config.num_dims),
        dtype=dtype,
        minval=jnp.asarray(config.init_low, dtype=dtype),
        maxval=jnp.asarray(config.init_high, dtype=dtype),
    )
    return from_population(population, config)


@functools.partial(jax.jit, static_argnames="config")
def initialize_fitness(state: DEState, fitness: ArrayLike, config: DEConfig) -> DEState:
    """Record the fitness of the current population (the first evaluation) and its best member.

    ``state.fitness`` is replaced by ``fitness`` and the best genome is recomputed from the
    population alone (any previous best is discarded); ``generation`` is unchanged.

    Args:
        state: a state from :func:`init` or :func:`from_population`.
        fitness: fitness of ``state.population``, shape ``(popsize,)``. NaN ranks worst.
        config: the DE settings.

    Returns:
        The state with ``fitness``, ``best_genome`` and ``best_fitness`` set.

    Raises:
        MbnInputError: ``fitness`` has the wrong shape.
    """
    _check_state(state, config)
    _check_shape(fitness, "fitness", (config.popsize,))
    fit = jnp.asarray(fitness, dtype=state.population.dtype)
    best = jnp.argmin(_rank_key(fit, config))
    return dataclasses.replace(
        state, fitness=fit, best_genome=state.population[best], best_fitness=fit[best]
    )


# ---------------------------------------------------------------------------------------------
# Variation: ask
# ---------------------------------------------------------------------------------------------


@functools.partial(jax.jit, static_argnames="config")
def apply_bounds(x: ArrayLike, config: DEConfig, resample_u: ArrayLike | None = None) -> Array:
    """Bring genes back into ``[lower, upper]`` by the bounds policy.

    ``"clip"``: a gene outside the box is set to the bound it violates. ``"reflect"``: a gene
    below ``lower`` becomes ``2 * lower - x`` and one above ``upper`` becomes ``2 * upper - x``
    (mirrored back into the box by the distance it overshot), then clipped if still outside
    (an overshoot larger than the box width). Reflection keeps trial genes off the bounds, where
    clipping piles them up. ``"resample"``: a gene outside the box becomes
    ``lower + resample_u * (upper - lower)``, a uniform random value in the box when
    ``resample_u`` is uniform in ``[0, 1)`` (scipy's rule; the result is clipped to guard
    against rounding). Genes inside the box are unchanged under every policy. Without bounds
    (``lower = upper = None``) ``x`` is returned unchanged; a missing side is unconstrained.

    The function is deterministic: the random draws of ``"resample"`` are an argument
    (:func:`ask` draws them from its key).

    Args:
        x: genes, shape ``(..., num_dims)``.
        config: the DE settings (``lower``, ``upper``, ``bounds_policy``).
        resample_u: for ``"resample"``, one draw in ``[0, 1)`` per gene, shape of ``x``; used
            only where a gene is out of bounds. Required with ``"resample"`` and bounds,
            ignored (after its shape check) otherwise.

    Returns:
        The bounded genes, same shape and dtype as ``x``.

    Raises:
        MbnInputError: ``resample_u`` has the wrong shape, or is missing with ``"resample"``.
    """
    x = jnp.asarray(x)
    if resample_u is not None:
        _check_shape(resample_u, "resample_u", x.shape)
    if not config.bounded:
        return x
    lo, hi = _bound_arrays(config, x.dtype)
    if config.bounds_policy == "reflect":
        x = jnp.where(x < lo, 2 * lo - x, jnp.where(x > hi, 2 * hi - x, x))
    elif config.bounds_policy == "resample":
        if resample_u is None:
            raise MbnInputError(
                "resample_u: required with bounds_policy='resample' (uniform draws in [0, 1), "
                f"shape {x.shape})"
            )
        u = jnp.asarray(resample_u, dtype=x.dtype)
        x = jnp.where((x < lo) | (x > hi), lo + u * (hi - lo), x)
    return jnp.clip(x, lo, hi)


@functools.partial(jax.jit, static_argnames="popsize")
def draw_partners(key: Array, popsize: int) -> tuple[Array, Array]:
    """Partner indices for DE/best/1: uniform ``r1 != r2`` with ``r1, r2 != i`` for every ``i``.

    Drawn without rejection: ``r1`` uniform over the ``popsize - 1`` indices other than ``i``,
    then ``r2`` uniform over the ``popsize - 2`` indices other than ``i`` and ``r1`` (an index
    drawn from a shorter range is shifted past the excluded ones).

    Args:
        key: a JAX PRNG key.
        popsize: population size, ``>= 3``.

    Returns:
        ``(r1, r2)``, each int32 of shape ``(popsize,)``, values in ``[0, popsize)``.
    """
    if popsize < 3:
        raise MbnInputError(f"popsize: must be >= 3 to draw two partners, got {popsize}")
    i = jnp.arange(popsize, dtype=jnp.int32)
    u1 = jax.random.randint(
        jax.random.fold_in(key, _PURPOSE_PARTNER_R1), (popsize,), 0, popsize - 1, dtype=jnp.int32
    )
    r1 = u1 + (u1 >= i)
    u2 = jax.random.randint(
        jax.random.fold_in(key, _PURPOSE_PARTNER_R2), (popsize,), 0, popsize - 2, dtype=jnp.int32
    )
    a, b = jnp.minimum(i, r1), jnp.maximum(i, r1)
    r2 = u2 + (u2 >= a)
    r2 = r2 + (r2 >= b)
    return r1, r2


@functools.partial(jax.jit, static_argnames=("popsize", "num_dims", "CR"))
def draw_cross_mask(key: Array, popsize: int, num_dims: int, CR: float) -> Array:
    """Binomial crossover mask with at least one crossed gene per row.

    Gene ``(i, j)`` is crossed (taken from the mutant) with probability ``CR``, independently,
    and gene ``(i, j_rand(i))`` always, with ``j_rand(i)`` uniform in ``[0, num_dims)``.

    Args:
        key: a JAX PRNG key.
        popsize: rows.
        num_dims: genes per row.
        CR: crossover rate in ``[0, 1]``.

    Returns:
        Boolean mask, shape ``(popsize, num_dims)``; True = the gene comes from the mutant.
    """
    u = jax.random.uniform(jax.random.fold_in(key, _PURPOSE_CROSSOVER), (popsize, num_dims))
    j_rand = jax.random.randint(
        jax.random.fold_in(key, _PURPOSE_J_RAND), (popsize,), 0, num_dims, dtype=jnp.int32
    )
    forced = jnp.arange(num_dims, dtype=jnp.int32)[None, :] == j_rand[:, None]
    return (u < CR) | forced


@functools.partial(jax.jit, static_argnames="config")
def mutate_crossover(
    best: ArrayLike,
    population: ArrayLike,
    r1: ArrayLike,
    r2: ArrayLike,
    cross_mask: ArrayLike,
    config: DEConfig,
    resample_u: ArrayLike | None = None,
) -> Array:
    """The deterministic core of DE/best/1/bin: mutation, crossover and the bounds policy.

    ``mutant[i] = best + F * (population[r1[i]] - population[r2[i]])``;
    ``trial = where(cross_mask, mutant, population)``; then :func:`apply_bounds` (with
    ``resample_u`` for ``"resample"``).

    Args:
        best: the best genome, shape ``(num_dims,)``.
        population: the current genomes (targets), shape ``(popsize, num_dims)``.
        r1: first partner index of each target, int, shape ``(popsize,)``.
        r2: second partner index of each target, int, shape ``(popsize,)``.
        cross_mask: True where the trial takes the mutant gene, bool, shape
            ``(popsize, num_dims)``.
        config: the DE settings (``F`` and the bounds).
        resample_u: for ``bounds_policy="resample"``, uniform draws in ``[0, 1)``, shape
            ``(popsize, num_dims)``; trial gene ``(i, j)`` out of bounds becomes
            ``lower_j + resample_u[i, j] * (upper_j - lower_j)``. Required with ``"resample"``
            and bounds, ignored otherwise.

    Returns:
        Trial genomes, shape ``(popsize, num_dims)``, dtype of ``population``.

    Raises:
        MbnInputError: an argument has the wrong shape, or ``resample_u`` is missing with
            ``"resample"``.
    """
    n, d = config.popsize, config.num_dims
    _check_shape(best, "best", (d,))
    _check_shape(population, "population", (n, d))
    _check_shape(r1, "r1", (n,))
    _check_shape(r2, "r2", (n,))
    _check_shape(cross_mask, "cross_mask", (n, d))
    if resample_u is not None:
        _check_shape(resample_u, "resample_u", (n, d))
    pop = jnp.asarray(population)
    best_ = jnp.asarray(best, dtype=pop.dtype)
    mutant = best_[None, :] + config.F * (pop[jnp.asarray(r1)] - pop[jnp.asarray(r2)])
    trial = jnp.where(jnp.asarray(cross_mask, dtype=bool), mutant, pop)
    return apply_bounds(trial, config, resample_u)


@functools.partial(jax.jit, static_argnames="config")
def ask(key: Array, state: DEState, config: DEConfig) -> Array:
    """The trial population of the next generation (DE/best/1/bin, deferred).

    The mutation uses ``state.best_genome``, so call :func:`initialize_fitness` first. The key is
    split by purpose (``jax.random.fold_in``): partner indices (:func:`draw_partners`),
    crossover draws and ``j_rand`` (:func:`draw_cross_mask`) and, for
    ``bounds_policy="resample"`` with bounds, the uniform replacement draws (one per gene, used
    where the trial gene is out of bounds). The other policies draw nothing extra.

    Args:
        key: a JAX PRNG key; the same key and state give bitwise the same trials.
        state: the current state.
        config: the DE settings.

    Returns:
        Trial genomes, shape ``(popsize, num_dims)``, inside the bounds when bounds are set.
    """
    _check_state(state, config)
    r1, r2 = draw_partners(key, config.popsize)
    mask = draw_cross_mask(key, config.popsize, config.num_dims, config.CR)
    resample_u = None
    if config.bounds_policy == "resample" and config.bounded:
        resample_u = jax.random.uniform(
            jax.random.fold_in(key, _PURPOSE_RESAMPLE),
            (config.popsize, config.num_dims),
            dtype=state.population.dtype,
        )
    return mutate_crossover(
        state.best_genome, state.population, r1, r2, mask, config, resample_u=resample_u
    )


# ---------------------------------------------------------------------------------------------
# Selection: tell
# ---------------------------------------------------------------------------------------------


@functools.partial(jax.jit, static_argnames="config")
def tell(state: DEState, trials: ArrayLike, trial_fitness: ArrayLike, config: DEConfig) -> DEState:
    """Greedy one-to-one replacement and best-so-far update; ``generation`` increases by one.

    Trial ``i`` replaces target ``i`` when its fitness is better or equal (``<=`` when
    minimising, ``>=`` when maximising, as in scipy); a NaN trial never wins and a NaN target
    loses to any number. The best genome is replaced by the best new member when that is better
    or equal, so ``best_fitness`` never worsens.

    Args:
        state: the state the trials were asked from.
        trials: trial genomes from :func:`ask`, shape ``(popsize, num_dims)``.
        trial_fitness: their fitness, shape ``(popsize,)``.
        config: the DE settings.

    Returns:
        The next state.

    Raises:
        MbnInputError: ``trials`` or ``trial_fitness`` has the wrong shape.
    """
    _check_state(state, config)
    _check_shape(trials, "trials", (config.popsize, config.num_dims))
    _check_shape(trial_fitness, "trial_fitness", (config.popsize,))
    dtype = state.population.dtype
    trials_ = jnp.asarray(trials, dtype=dtype)
    trial_fit = jnp.asarray(trial_fitness, dtype=dtype)
    wins = _better_or_equal(trial_fit, state.fitness, config)
    population = jnp.where(wins[:, None], trials_, state.population)
    fitness = jnp.where(wins, trial_fit, state.fitness)
    idx = jnp.argmin(_rank_key(fitness, config))
    improved = _better_or_equal(fitness[idx], state.best_fitness, config)
    return DEState(
        population=population,
        fitness=fitness,
        best_genome=jnp.where(improved, population[idx], state.best_genome),
        best_fitness=jnp.where(improved, fitness[idx], state.best_fitness),
        generation=state.generation + 1,
    )


# ---------------------------------------------------------------------------------------------
# Convenience loop
# ---------------------------------------------------------------------------------------------


@functools.partial(jax.jit, static_argnames=("fitness_fn", "config", "num_generations"))
def _run(
    fitness_fn: Callable[[Array], Array],
    key: Array,
    population: Array | None,
    config: DEConfig,
    num_generations: int,
) -> tuple[DEState, Array]:
    if population is None:
        state = init(jax.random.fold_in(key, _PURPOSE_INIT), config)
    else:
        state = from_population(population, config)
    state = initialize_fitness(state, fitness_fn(state.population), config)

    def generation(state: DEState, gen_key: Array) -> tuple[DEState, Array]:
        trials = ask(gen_key, state, config)
        state = tell(state, trials, fitness_fn(trials), config)
        return state, state.best_fitness

    keys = jax.random.split(jax.random.fold_in(key, _PURPOSE_GENERATIONS), num_generations)
    return jax.lax.scan(generation, state, keys)


def minimize(
    fitness_fn: Callable[[Array], Array],
    key: Array,
    config: DEConfig,
    num_generations: int,
    *,
    population: ArrayLike | None = None,
) -> tuple[DEState, Array]:
    """Run DE for ``num_generations`` generations in one jitted ``lax.scan``.

    Despite the name (after ``scipy.optimize``), the direction follows ``config.maximize``.
    ``fitness_fn`` is a static argument of the compiled loop: pass the same function object to
    reuse the compilation. The function is vmap-able over ``key`` and ``population``.

    Args:
        fitness_fn: jittable map from genomes ``(popsize, num_dims)`` to fitness ``(popsize,)``.
        key: a JAX PRNG key.
        config: the DE settings.
        num_generations: generations to run, ``>= 0``; each costs ``popsize`` evaluations, plus
            ``popsize`` for the initial population.
        population: optional initial population, shape ``(popsize, num_dims)``; default drawn by
            :func:`init`.

    Returns:
        ``(state, history)``: the final state and the best fitness after each generation, shape
        ``(num_generations,)``.

    Raises:
        MbnInputError: ``num_generations`` is not an integer ``>= 0``, or a shape is wrong.
    """
    if not _is_int(num_generations) or num_generations < 0:
        raise MbnInputError(f"num_generations: must be an integer >= 0, got {num_generations!r}")
    pop = None if population is None else jnp.asarray(population)
    return _run(fitness_fn, key, pop, config, int(num_generations))
