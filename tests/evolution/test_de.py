"""Tests of mbn.evolution.de: DE/best/1/bin with deferred ask/tell."""

from __future__ import annotations

import dataclasses
import functools
import itertools

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import scipy.optimize  # noqa: E402
import scipy.stats  # noqa: E402
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis.extra import numpy as hnp  # noqa: E402

from mbn.errors import MbnInputError  # noqa: E402
from mbn.evolution import (  # noqa: E402
    DEConfig,
    DEState,
    apply_bounds,
    ask,
    draw_cross_mask,
    draw_partners,
    from_population,
    init,
    initialize_fitness,
    minimize,
    mutate_crossover,
    tell,
)

HYPOTHESIS = settings(max_examples=25, deadline=None)


def sphere(X: jax.Array) -> jax.Array:
    return jnp.sum(X**2, axis=-1)


def neg_sphere(X: jax.Array) -> jax.Array:
    return -jnp.sum(X**2, axis=-1)


def rastrigin(X: jax.Array) -> jax.Array:
    return 10.0 * X.shape[-1] + jnp.sum(X**2 - 10.0 * jnp.cos(2.0 * jnp.pi * X), axis=-1)


def np_sphere(x: np.ndarray) -> float:
    return float(np.sum(x**2))


def np_rastrigin(x: np.ndarray) -> float:
    return float(10.0 * x.size + np.sum(x**2 - 10.0 * np.cos(2.0 * np.pi * x)))


def evaluated_state(key: jax.Array, config: DEConfig) -> DEState:
    state = init(key, config)
    return initialize_fitness(state, sphere(state.population), config)


# ---------------------------------------------------------------------------------------------
# 1. One generation by hand
# ---------------------------------------------------------------------------------------------

HAND_POP = np.array(
    [
        [0.0, 1.0, 2.0],
        [1.0, -1.0, 0.5],
        [2.0, 0.0, -1.0],
        [-1.0, 3.0, 1.0],
        [0.5, 0.5, 0.5],
    ]
)
HAND_BEST = HAND_POP[0]
HAND_R1 = np.array([1, 2, 3, 4, 0])
HAND_R2 = np.array([2, 3, 4, 0, 1])
HAND_MASK = np.array(
    [
        [True, False, False],
        [False, True, False],
        [False, False, True],
        [True, True, True],
        [False, False, False],
    ]
)
# With F = 0.5, mutant_i = best + 0.5 * (pop[r1_i] - pop[r2_i]):
#   i=0: [0,1,2] + 0.5*([1,-1,0.5] - [2,0,-1])  = [-0.5,  0.5,  2.75]
#   i=1: [0,1,2] + 0.5*([2,0,-1]   - [-1,3,1])  = [ 1.5, -0.5,  1.0 ]
#   i=2: [0,1,2] + 0.5*([-1,3,1]   - [.5,.5,.5])= [-0.75, 2.25, 2.25]
#   i=3: [0,1,2] + 0.5*([.5,.5,.5] - [0,1,2])   = [ 0.25, 0.75, 1.25]
#   i=4: [0,1,2] + 0.5*([0,1,2]    - [1,-1,.5]) = [-0.5,  2.0,  2.75]
# and the trial takes the mutant gene where the mask is True, else the target's gene.
HAND_TRIAL_UNBOUNDED = np.array(
    [
        [-0.5, 1.0, 2.0],
        [1.0, -0.5, 0.5],
        [2.0, 0.0, 2.25],
        [0.25, 0.75, 1.25],
        [0.5, 0.5, 0.5],
    ]
)
# Per-gene bounds lower = (-0.25, -1, -1), upper = (3, 3, 2): only trial[0, 0] = -0.5 (below
# -0.25) and trial[2, 2] = 2.25 (above 2) are outside.
#   clip:    -0.5 -> -0.25;                 2.25 -> 2.0
#   reflect: -0.5 -> 2*(-0.25) - (-0.5) = 0; 2.25 -> 2*2 - 2.25 = 1.75
HAND_LOWER = (-0.25, -1.0, -1.0)
HAND_UPPER = (3.0, 3.0, 2.0)
HAND_TRIAL_CLIP = HAND_TRIAL_UNBOUNDED.copy()
HAND_TRIAL_CLIP[0, 0] = -0.25
HAND_TRIAL_CLIP[2, 2] = 2.0
HAND_TRIAL_REFLECT = HAND_TRIAL_UNBOUNDED.copy()
HAND_TRIAL_REFLECT[0, 0] = 0.0
HAND_TRIAL_REFLECT[2, 2] = 1.75
# resample, with draws u = 0.5 everywhere except u[0, 0] = 0.2 and u[2, 2] = 0.75 (the draws of
# the in-bounds genes are not used):
#   -0.5 -> lower + u * (upper - lower) = -0.25 + 0.2 * 3.25 = 0.4;  2.25 -> -1 + 0.75 * 3 = 1.25
HAND_RESAMPLE_U = np.full((5, 3), 0.5)
HAND_RESAMPLE_U[0, 0] = 0.2
HAND_RESAMPLE_U[2, 2] = 0.75
HAND_TRIAL_RESAMPLE = HAND_TRIAL_UNBOUNDED.copy()
HAND_TRIAL_RESAMPLE[0, 0] = 0.4
HAND_TRIAL_RESAMPLE[2, 2] = 1.25


@pytest.mark.parametrize(
    ("bounds", "policy", "resample_u", "expected"),
    [
        (None, "clip", None, HAND_TRIAL_UNBOUNDED),
        (None, "resample", None, HAND_TRIAL_UNBOUNDED),
        ((HAND_LOWER, HAND_UPPER), "clip", None, HAND_TRIAL_CLIP),
        ((HAND_LOWER, HAND_UPPER), "reflect", None, HAND_TRIAL_REFLECT),
        ((HAND_LOWER, HAND_UPPER), "resample", HAND_RESAMPLE_U, HAND_TRIAL_RESAMPLE),
    ],
)
def test_mutate_crossover_matches_hand_computed_generation(
    bounds: tuple[tuple[float, ...], tuple[float, ...]] | None,
    policy: str,
    resample_u: np.ndarray | None,
    expected: np.ndarray,
) -> None:
    lower, upper = bounds if bounds is not None else (None, None)
    config = DEConfig(
        num_dims=3,
        popsize=5,
        F=0.5,
        init_low=-0.25,
        init_high=2.0,
        lower=lower,
        upper=upper,
        bounds_policy=policy,
    )
    trial = mutate_crossover(
        jnp.asarray(HAND_BEST),
        jnp.asarray(HAND_POP),
        jnp.asarray(HAND_R1),
        jnp.asarray(HAND_R2),
        jnp.asarray(HAND_MASK),
        config,
        resample_u=None if resample_u is None else jnp.asarray(resample_u),
    )
    assert trial.dtype == jnp.float64
    np.testing.assert_allclose(np.asarray(trial), expected, rtol=0, atol=1e-15)


def test_apply_bounds_clip_reflect_and_resample_by_hand() -> None:
    # Box [0, 1]; reflection of -3 gives 3 and of 4 gives -2, both still outside -> clipped.
    x = jnp.array([[-0.25, 1.5, -3.0, 4.0, 0.5]])
    box = {"num_dims": 5, "init_low": 0.0, "init_high": 1.0, "lower": 0.0, "upper": 1.0}
    clip = DEConfig(**box, bounds_policy="clip")
    reflect = DEConfig(**box, bounds_policy="reflect")
    np.testing.assert_allclose(apply_bounds(x, clip), [[0.0, 1.0, 0.0, 1.0, 0.5]], atol=1e-15)
    np.testing.assert_allclose(apply_bounds(x, reflect), [[0.25, 0.5, 1.0, 0.0, 0.5]], atol=1e-15)
    one_sided = DEConfig(**(box | {"upper": None}), bounds_policy="reflect")
    np.testing.assert_allclose(apply_bounds(x, one_sided), [[0.25, 1.5, 3.0, 4.0, 0.5]], atol=1e-15)
    np.testing.assert_array_equal(apply_bounds(x, DEConfig(num_dims=5)), x)
    # resample: the out-of-bounds genes take lower + u * (upper - lower) = u; 0.5 keeps its value.
    resample = DEConfig(**box, bounds_policy="resample")
    u = jnp.array([[0.1, 0.2, 0.3, 0.4, 0.9]])
    np.testing.assert_allclose(apply_bounds(x, resample, u), [[0.1, 0.2, 0.3, 0.4, 0.5]], atol=0)
    # Per-gene box [-2, 2] x [10, 20]: 3 -> -2 + 0.25 * 4 = -1; 5 -> 10 + 0.5 * 10 = 15.
    per_gene = DEConfig(
        num_dims=2,
        init_low=(-2, 10),
        init_high=(2, 20),
        lower=(-2, 10),
        upper=(2, 20),
        bounds_policy="resample",
    )
    x2, u2 = jnp.array([[3.0, 5.0], [0.0, 12.0]]), jnp.array([[0.25, 0.5], [0.25, 0.5]])
    np.testing.assert_allclose(apply_bounds(x2, per_gene, u2), [[-1.0, 15.0], [0.0, 12.0]], atol=0)
    # The draws are required with bounds, must match x's shape, and are not needed without bounds.
    with pytest.raises(MbnInputError, match=r"^resample_u:"):
        apply_bounds(x, resample)
    with pytest.raises(MbnInputError, match=r"^resample_u:"):
        apply_bounds(x, resample, u[:, :4])
    unbounded = DEConfig(num_dims=5, bounds_policy="resample")
    np.testing.assert_array_equal(apply_bounds(x, unbounded), x)


def test_ask_with_resample_replaces_exactly_the_clipped_genes_by_uniform_values() -> None:
    # Same key -> same partners and crossover mask for both policies: where the clipped trial is
    # strictly inside the box the resampled trial is identical; where clipping put a gene on a
    # bound (it was outside), resampling gives a uniform value in the box instead.
    box = {"num_dims": 6, "popsize": 10, "F": 2.0, "CR": 0.9, "lower": -1.0, "upper": 1.0}
    box |= {"init_low": -1.0, "init_high": 1.0}
    clip = DEConfig(**box, bounds_policy="clip")
    resample = DEConfig(**box, bounds_policy="resample")
    replaced = []
    for k in range(40):
        state = evaluated_state(jax.random.key(1000 + k), clip)
        key = jax.random.key(2000 + k)
        t_clip = np.asarray(ask(key, state, clip))
        t_res = np.asarray(ask(key, state, resample))
        np.testing.assert_array_equal(t_res, np.asarray(ask(key, state, resample)))  # bitwise
        on_bound = np.abs(t_clip) == 1.0
        np.testing.assert_array_equal(t_res[~on_bound], t_clip[~on_bound])
        replaced.append(t_res[on_bound])
    values = np.concatenate(replaced)
    assert values.size > 500, values.size  # F = 2 pushes many genes out
    assert np.all((values >= -1.0) & (values <= 1.0))
    assert scipy.stats.kstest((values + 1.0) / 2.0, "uniform").pvalue > 1e-3


# ---------------------------------------------------------------------------------------------
# 2. Partners r1 != r2 != i, at least one crossed gene
# ---------------------------------------------------------------------------------------------


def _valid_pairs(n: int, i: int) -> list[tuple[int, int]]:
    return [(a, b) for a, b in itertools.permutations(range(n), 2) if i not in (a, b)]


def _matching_pairs(
    value: np.ndarray, best: np.ndarray, pop: np.ndarray, F: float
) -> list[tuple[int, int]]:
    """All ordered pairs (a, b), a != b, with best + F * (pop[a] - pop[b]) == value (1e-12)."""
    return [
        (a, b)
        for a, b in itertools.permutations(range(len(pop)), 2)
        if np.allclose(best + F * (pop[a] - pop[b]), value, rtol=0, atol=1e-12)
    ]


def test_ask_with_cr0_changes_exactly_one_gene_by_a_valid_mutant() -> None:
    config = DEConfig(num_dims=5, popsize=6, CR=0.0, F=0.85)
    state = evaluated_state(jax.random.key(3), config)
    pop, best = np.asarray(state.population), np.asarray(state.best_genome)
    crossed_genes = set()
    for k in range(20):
        trials = np.asarray(ask(jax.random.key(100 + k), state, config))
        changed = trials != pop
        np.testing.assert_array_equal(changed.sum(axis=1), np.ones(config.popsize, dtype=int))
        for i in range(config.popsize):
            j = int(np.flatnonzero(changed[i])[0])
            crossed_genes.add(j)
            pairs = _matching_pairs(trials[i, j : j + 1], best[j : j + 1], pop[:, j : j + 1], 0.85)
            assert pairs, f"trial {i} gene {j} is not best + F*(x_r1 - x_r2) for any pair"
            assert all(i not in pair for pair in pairs), f"trial {i} used itself: {pairs}"
    assert crossed_genes == set(range(config.num_dims))  # j_rand reaches every gene


def test_ask_with_cr1_takes_every_gene_from_a_valid_mutant() -> None:
    config = DEConfig(num_dims=4, popsize=7, CR=1.0, F=0.85)
    state = evaluated_state(jax.random.key(4), config)
    pop, best = np.asarray(state.population), np.asarray(state.best_genome)
    for k in range(10):
        trials = np.asarray(ask(jax.random.key(200 + k), state, config))
        for i in range(config.popsize):
            pairs = _matching_pairs(trials[i], best, pop, 0.85)
            assert len(pairs) == 1, f"trial {i}: expected one mutant pair, got {pairs}"
            assert pairs[0] in _valid_pairs(config.popsize, i)


def test_draw_partners_are_distinct_from_each_other_and_target_and_uniform() -> None:
    n, draws = 5, 2400
    keys = jax.random.split(jax.random.key(5), draws)
    r1, r2 = jax.vmap(draw_partners, in_axes=(0, None))(keys, n)
    r1, r2 = np.asarray(r1), np.asarray(r2)
    i = np.arange(n)
    assert np.all(r1 != r2) and np.all(r1 != i) and np.all(r2 != i)
    # 12 valid ordered pairs per target, expected 200 each, sd ~ 13.8; allow +-5 sd.
    for target in range(n):
        counts = {pair: 0 for pair in _valid_pairs(n, target)}
        for a, b in zip(r1[:, target], r2[:, target], strict=True):
            counts[(int(a), int(b))] += 1
        assert min(counts.values()) >= 130 and max(counts.values()) <= 270, counts


def test_draw_cross_mask_rate_and_at_least_one_crossed_gene() -> None:
    keys = jax.random.split(jax.random.key(6), 400)
    masks = np.asarray(jax.vmap(draw_cross_mask, in_axes=(0, None, None, None))(keys, 8, 6, 0.2))
    assert np.all(masks.sum(axis=-1) >= 1)
    # P(crossed) = CR + (1 - CR) / D = 0.2 + 0.8 / 6; 19200 genes: sd ~ 0.0034.
    assert abs(masks.mean() - (0.2 + 0.8 / 6)) < 0.015
    only_jrand = np.asarray(
        jax.vmap(draw_cross_mask, in_axes=(0, None, None, None))(keys, 8, 6, 0.0)
    )
    np.testing.assert_array_equal(only_jrand.sum(axis=-1), np.ones((400, 8), dtype=int))
    # j_rand uniform over the 6 genes: 3200 draws, expected 533 each, sd ~ 21.
    counts = only_jrand.reshape(-1, 6).sum(axis=0)
    assert counts.min() >= 430 and counts.max() <= 640, counts


# ---------------------------------------------------------------------------------------------
# 3. Invariants (hypothesis)
# ---------------------------------------------------------------------------------------------

BOUNDED_CONFIGS = (
    DEConfig(
        num_dims=3,
        popsize=6,
        F=2.0,
        init_low=-1.0,
        init_high=2.0,
        lower=-1.0,
        upper=2.0,
        bounds_policy="clip",
    ),
    DEConfig(
        num_dims=3,
        popsize=6,
        F=2.0,
        CR=0.9,
        init_low=(-1, 0, 5),
        init_high=(1, 0.5, 50),
        lower=(-1, 0, 5),
        upper=(1, 0.5, 50),
        bounds_policy="reflect",
    ),
    DEConfig(
        num_dims=3,
        popsize=6,
        F=2.0,
        CR=0.9,
        init_low=(-0.5, 0, 10),
        init_high=(0.5, 0.5, 20),
        lower=(-1, 0, 5),
        upper=(1, 0.5, 50),
        bounds_policy="resample",
    ),
)


@settings(max_examples=12, deadline=None)  # each example compiles its own trials (a new config)
@given(
    config=st.sampled_from(BOUNDED_CONFIGS),
    population=hnp.arrays(
        np.float64, (6, 3), elements=st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
    ),
    seed=st.integers(0, 2**31 - 1),
)
def test_children_stay_inside_bounds_for_every_policy(
    config: DEConfig, population: np.ndarray, seed: int
) -> None:
    state = from_population(population, config)
    state = initialize_fitness(state, sphere(state.population), config)
    lo = np.broadcast_to(np.asarray(config.lower), (3,))
    hi = np.broadcast_to(np.asarray(config.upper), (3,))
    assert np.all(np.asarray(state.population) >= lo) and np.all(np.asarray(state.population) <= hi)
    trials = np.asarray(ask(jax.random.key(seed), state, config))
    assert np.all(trials >= lo) and np.all(trials <= hi)
    # The raw core, fed the unbounded population and a random mutant choice, too.
    k1, k2, k3 = jax.random.split(jax.random.key(seed), 3)
    r1, r2 = draw_partners(k1, 6)
    mask = draw_cross_mask(k2, 6, 3, config.CR)
    u = jax.random.uniform(k3, (6, 3)) if config.bounds_policy == "resample" else None
    raw = np.asarray(
        mutate_crossover(population[0], population, r1, r2, mask, config, resample_u=u)
    )
    assert np.all(raw >= lo) and np.all(raw <= hi)


QUADRATIC_CONFIG = DEConfig(
    num_dims=4, popsize=8, lower=-10.0, upper=10.0, init_low=-10.0, init_high=10.0
)


@HYPOTHESIS
@given(seed=st.integers(0, 2**31 - 1))
def test_best_never_worsens_on_random_quadratic(seed: int) -> None:
    rng = np.random.default_rng(seed)
    scale = rng.uniform(0.1, 10.0, 4)
    centre = rng.uniform(-5.0, 5.0, 4)

    def f(X: jax.Array) -> jax.Array:
        return jnp.sum(scale * (X - centre) ** 2, axis=-1)

    config = QUADRATIC_CONFIG
    key = jax.random.key(seed)
    state = init(jax.random.fold_in(key, 0), config)
    state = initialize_fitness(state, f(state.population), config)
    best = [float(state.best_fitness)]
    for g in range(6):
        trials = ask(jax.random.fold_in(key, g + 1), state, config)
        state = tell(state, trials, f(trials), config)
        best.append(float(state.best_fitness))
        assert int(state.generation) == g + 1
    assert all(b1 <= b0 for b0, b1 in itertools.pairwise(best)), best
    assert float(state.best_fitness) == float(jnp.min(state.fitness))
    np.testing.assert_allclose(float(f(state.best_genome)), best[-1], rtol=1e-12, atol=0)


# Subnormal floats are excluded: XLA on CPU flushes them to zero in comparisons, so a
# subnormal best-so-far compares equal to 0.0 (a platform property, not a DE rule).
fitness_values = st.one_of(
    st.sampled_from([0.0, 1.0, -1.0, np.nan, np.inf, -np.inf]),
    st.floats(-10.0, 10.0, allow_nan=False, allow_subnormal=False),
)


@HYPOTHESIS
@given(
    target_fitness=st.lists(fitness_values, min_size=5, max_size=5),
    trial_fitness=st.lists(fitness_values, min_size=5, max_size=5),
    old_best=fitness_values,
    maximize=st.booleans(),
)
def test_tell_keeps_the_better_of_target_and_trial(
    target_fitness: list[float], trial_fitness: list[float], old_best: float, maximize: bool
) -> None:
    config = DEConfig(num_dims=2, popsize=5, maximize=maximize)
    population = np.arange(10.0).reshape(5, 2)
    trials = -1.0 - np.arange(10.0).reshape(5, 2)
    state = DEState(
        population=jnp.asarray(population),
        fitness=jnp.asarray(target_fitness),
        best_genome=jnp.array([100.0, 100.0]),
        best_fitness=jnp.asarray(old_best),
        generation=jnp.asarray(3, dtype=jnp.int32),
    )
    new = tell(state, jnp.asarray(trials), jnp.asarray(trial_fitness), config)

    def at_least_as_good(a: float, b: float) -> bool:
        if np.isnan(a):
            return False
        return bool(np.isnan(b) or (a >= b if maximize else a <= b))

    wins = [at_least_as_good(a, b) for a, b in zip(trial_fitness, target_fitness, strict=True)]
    for i, win in enumerate(wins):
        np.testing.assert_array_equal(new.population[i], trials[i] if win else population[i])
        np.testing.assert_array_equal(
            new.fitness[i], trial_fitness[i] if win else target_fitness[i]
        )
    assert int(new.generation) == 4
    # The best never worsens; NaN never becomes the best over a number.
    new_best = float(new.best_fitness)
    candidates = [v for v in np.asarray(new.fitness) if not np.isnan(v)]
    if not np.isnan(old_best):
        assert at_least_as_good(new_best, old_best)
    if candidates:
        top = max(candidates) if maximize else min(candidates)
        assert new_best == top or (at_least_as_good(old_best, top) and new_best == old_best)


def test_initialize_fitness_picks_best_and_ignores_nan() -> None:
    config = DEConfig(num_dims=2, popsize=4)
    state = from_population(jnp.arange(8.0).reshape(4, 2), config)
    assert np.all(np.isposinf(np.asarray(state.fitness))) and int(state.generation) == 0
    state = initialize_fitness(state, jnp.array([3.0, np.nan, 1.0, 2.0]), config)
    assert float(state.best_fitness) == 1.0
    np.testing.assert_array_equal(state.best_genome, [4.0, 5.0])
    up = initialize_fitness(
        state, jnp.array([3.0, np.nan, 1.0, 2.0]), dataclasses.replace(config, maximize=True)
    )
    assert float(up.best_fitness) == 3.0


def test_init_is_uniform_in_init_range_and_float64() -> None:
    config = DEConfig(num_dims=30, popsize=18)
    state = init(jax.random.key(0), config)
    pop = np.asarray(state.population)
    assert state.population.dtype == jnp.float64 and state.fitness.dtype == jnp.float64
    assert pop.shape == (18, 30) and state.fitness.shape == (18,)
    assert pop.min() >= -100.0 and pop.max() <= 100.0
    # 540 uniform draws on [-100, 100]: mean sd ~ 2.5, sd of the sample sd ~ 1.3.
    assert abs(pop.mean()) < 12.0 and abs(pop.std() - 200 / np.sqrt(12)) < 6.0
    assert np.all(np.isposinf(np.asarray(state.fitness)))
    assert float(state.best_fitness) == np.inf and int(state.generation) == 0


def test_init_with_per_gene_range() -> None:
    config = DEConfig(
        num_dims=3,
        popsize=200,
        init_low=(-1.0, 10.0, 0.0),
        init_high=(1.0, 20.0, 0.001),
        lower=(-1.0, 0.0, 0.0),
        upper=(1.0, 50.0, 1.0),
    )
    pop = np.asarray(init(jax.random.key(1), config).population)
    np.testing.assert_array_less([-1.0 - 1e-12, 10.0 - 1e-12, -1e-12], pop.min(axis=0))
    np.testing.assert_array_less(pop.max(axis=0), [1.0, 20.0, 0.001])
    assert pop[:, 0].min() < -0.9 and pop[:, 1].max() > 19.0  # spread over the whole range


def test_tell_rejects_wrong_shapes() -> None:
    config = DEConfig(num_dims=3, popsize=5)
    state = evaluated_state(jax.random.key(0), config)
    with pytest.raises(MbnInputError, match="trial_fitness"):
        tell(state, state.population, jnp.zeros(4), config)
    with pytest.raises(MbnInputError, match="trials"):
        tell(state, state.population[:, :2], jnp.zeros(5), config)


# ---------------------------------------------------------------------------------------------
# 4. Determinism
# ---------------------------------------------------------------------------------------------


SMALL_CONFIG = DEConfig(
    num_dims=6,
    popsize=12,
    init_low=-5.0,
    init_high=5.0,
    lower=-5.0,
    upper=5.0,
    bounds_policy="reflect",
)


def test_same_key_gives_bitwise_identical_results() -> None:
    config = SMALL_CONFIG
    a = evaluated_state(jax.random.key(11), config)
    b = evaluated_state(jax.random.key(11), config)
    np.testing.assert_array_equal(a.population, b.population)
    ta, tb = ask(jax.random.key(12), a, config), ask(jax.random.key(12), b, config)
    np.testing.assert_array_equal(ta, tb)
    assert not np.array_equal(ta, ask(jax.random.key(13), a, config))
    for cfg in (config, dataclasses.replace(config, bounds_policy="resample")):
        (sa, ha), (sb, hb) = (minimize(sphere, jax.random.key(14), cfg, 40) for _ in range(2))
        leaves_a, leaves_b = jax.tree.leaves((sa, ha)), jax.tree.leaves((sb, hb))
        for leaf_a, leaf_b in zip(leaves_a, leaves_b, strict=True):
            np.testing.assert_array_equal(leaf_a, leaf_b)


# ---------------------------------------------------------------------------------------------
# 5. Against scipy, and maximisation
# ---------------------------------------------------------------------------------------------

# 12 genes in [-5.12, 5.12]; population 40 (given to scipy as its `init` array, so both start from
# the same members); medians over seeds 0..9. Ours uses bounds_policy="resample", scipy's own rule
# for out-of-bounds genes (a uniform random value in the box), so the bounds step is like for like.
# G = 200 generations (8040 evaluations per run), the acceptance setting. Measured medians of the
# final best, ours (resample) / scipy (default updating="immediate"), scipy 1.17.1, jax 0.10.2:
#   G = 100: sphere 0.02376 / 0.01912 = 1.24,      Rastrigin 24.23 / 26.57 = 0.91
#   G = 150: sphere 7.18e-4 / 4.205e-4 = 1.71,     Rastrigin 13.73 / 13.90 = 0.99
#   G = 200: sphere 2.135e-5 / 1.259e-5 = 1.70,    Rastrigin 6.941 / 6.843 = 1.01
# (with "clip" instead, sphere at G = 200 is 2.535e-5, ratio 2.01: it fails the 2x target). On
# sphere the ratio grows with G: scipy's immediate updating uses each new best within the
# generation, ours is deferred (see docs/de.md).
SCIPY_DIMS, SCIPY_POPSIZE, SCIPY_GENERATIONS, SCIPY_SEEDS, SCIPY_BOUND = 12, 40, 200, 10, 5.12
SCIPY_FUNCTIONS = {"sphere": (sphere, np_sphere), "rastrigin": (rastrigin, np_rastrigin)}


def _initial_populations() -> np.ndarray:
    shape = (SCIPY_POPSIZE, SCIPY_DIMS)
    return np.stack(
        [
            np.random.default_rng(s).uniform(-SCIPY_BOUND, SCIPY_BOUND, shape)
            for s in range(SCIPY_SEEDS)
        ]
    )


@functools.cache
def _our_median(name: str) -> float:
    config = DEConfig(
        num_dims=SCIPY_DIMS,
        popsize=SCIPY_POPSIZE,
        init_low=-SCIPY_BOUND,
        init_high=SCIPY_BOUND,
        lower=-SCIPY_BOUND,
        upper=SCIPY_BOUND,
        bounds_policy="resample",
    )
    fn = SCIPY_FUNCTIONS[name][0]
    keys = jax.vmap(jax.random.key)(jnp.arange(SCIPY_SEEDS))
    run = jax.vmap(lambda k, p: minimize(fn, k, config, SCIPY_GENERATIONS, population=p))
    state, history = run(keys, jnp.asarray(_initial_populations()))
    assert history.shape == (SCIPY_SEEDS, SCIPY_GENERATIONS)
    assert np.all(np.diff(np.asarray(history), axis=1) <= 0)
    return float(np.median(np.asarray(state.best_fitness)))


@functools.cache
def _scipy_median(name: str, updating: str) -> float:
    fn = SCIPY_FUNCTIONS[name][1]
    pops = _initial_populations()
    best = [
        scipy.optimize.differential_evolution(
            fn,
            [(-SCIPY_BOUND, SCIPY_BOUND)] * SCIPY_DIMS,
            strategy="best1bin",
            mutation=0.85,
            recombination=0.2,
            polish=False,
            tol=0,
            maxiter=SCIPY_GENERATIONS,
            init=pops[s],
            seed=s,
            updating=updating,
        ).fun
        for s in range(SCIPY_SEEDS)
    ]
    return float(np.median(best))


@pytest.mark.slow
@pytest.mark.parametrize("name", ["sphere", "rastrigin"])
def test_final_best_within_twice_scipy_best1bin_median(name: str) -> None:
    ours, theirs = _our_median(name), _scipy_median(name, "immediate")
    assert ours <= 2.0 * theirs, f"{name}: ours {ours:.3g} vs scipy (immediate) {theirs:.3g}"


@pytest.mark.slow
@pytest.mark.parametrize("name", ["sphere", "rastrigin"])
def test_scipy_deferred_comparison(name: str) -> None:
    ours, theirs = _our_median(name), _scipy_median(name, "deferred")
    assert ours <= 2.0 * theirs, f"{name}: ours {ours:.3g} vs scipy (deferred) {theirs:.3g}"


def test_maximize_mirrors_minimize_bitwise() -> None:
    config = SMALL_CONFIG
    down, h_down = minimize(sphere, jax.random.key(21), config, 40)
    up, h_up = minimize(
        neg_sphere, jax.random.key(21), dataclasses.replace(config, maximize=True), 40
    )
    np.testing.assert_array_equal(up.population, down.population)
    np.testing.assert_array_equal(up.fitness, -down.fitness)
    np.testing.assert_array_equal(h_up, -h_down)
    assert np.all(np.diff(np.asarray(h_up)) >= 0)  # larger is better: history never decreases
    assert float(up.best_fitness) > -1.0  # from ~ -50 at the start towards the maximum 0


def test_unevaluated_maximize_state_starts_at_minus_infinity() -> None:
    config = DEConfig(num_dims=2, popsize=4, maximize=True)
    state = init(jax.random.key(0), config)
    assert np.all(np.isneginf(np.asarray(state.fitness))) and float(state.best_fitness) == -np.inf


# ---------------------------------------------------------------------------------------------
# 6. Bad configuration
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "parameter"),
    [
        ({"num_dims": 0}, "num_dims"),
        ({"num_dims": 2.5}, "num_dims"),
        ({"popsize": 3}, "popsize"),
        ({"popsize": True}, "popsize"),
        ({"F": 0.0}, "F"),
        ({"F": 3.0}, "F"),
        ({"F": float("nan")}, "F"),
        ({"CR": -0.1}, "CR"),
        ({"CR": 1.5}, "CR"),
        ({"init_low": 1.0, "init_high": 1.0}, "init_low"),
        ({"init_high": float("inf")}, "init_high"),
        ({"init_low": None}, "init_low"),
        ({"init_low": (0.0, 1.0, 2.0)}, "init_low"),
        ({"init_low": (0.0, 2.0), "init_high": (1.0, 1.0)}, "init_low"),
        ({"lower": -1.0, "upper": 1.0}, "init_low"),  # default init range [-100, 100]
        ({"lower": -200.0, "upper": 1.0}, "init_high"),
        ({"init_low": 0.0, "init_high": 1.0, "lower": (0.0, 0.5)}, "init_low"),
        ({"init_low": 0.0, "init_high": 1.0, "upper": (1.0, 0.5)}, "init_high"),
        ({"init_low": 0, "init_high": 1, "lower": 0, "bounds_policy": "resample"}, "bounds_policy"),
        ({"lower": 1.0, "upper": 0.0}, "lower"),
        ({"lower": (0.0, 0.0, 0.0)}, "lower"),
        ({"upper": float("nan")}, "upper"),
        ({"upper": "high"}, "upper"),
        ({"bounds_policy": "wrap"}, "bounds_policy"),
        ({"maximize": "yes"}, "maximize"),
    ],
)
def test_bad_config_raises_naming_the_parameter(kwargs: dict, parameter: str) -> None:
    with pytest.raises(MbnInputError, match=rf"^{parameter}:"):
        DEConfig(**{"num_dims": 2, **kwargs})


def test_initial_range_must_lie_inside_the_bounds() -> None:
    # The default initial range [-100, 100] with bounds [-1, 1] would put nearly every initial
    # gene on a bound after clipping, where DE stalls: rejected, naming init_low/init_high and
    # the bounds of the offending gene.
    expected = r"^init_low: .*\[init_low, init_high\].*\[lower, upper\]"
    with pytest.raises(MbnInputError, match=expected) as err:
        DEConfig(num_dims=4, lower=-1.0, upper=1.0)
    assert "[-100.0, 100.0]" in str(err.value) and "[-1.0, 1.0] at gene 0" in str(err.value)
    with pytest.raises(MbnInputError, match=r"^init_high: .*\[2.0, 3.5\].* at gene 2$"):
        DEConfig(num_dims=3, init_low=2.0, init_high=3.5, lower=0.0, upper=(4.0, 5.0, 3.0))
    # Touching the bounds is allowed, and so are one-sided bounds the range respects.
    DEConfig(num_dims=3, init_low=-1.0, init_high=1.0, lower=-1.0, upper=1.0)
    DEConfig(num_dims=3, lower=-100.0)
    DEConfig(num_dims=3, upper=(100.0, 200.0, 300.0), bounds_policy="reflect")
    # Per-gene initial ranges fit per-gene bounds that a single scalar range could not.
    DEConfig(num_dims=2, init_low=(-1, 5), init_high=(1, 9), lower=(-1, 5), upper=(1, 10))


def test_minimize_rejects_negative_generations() -> None:
    with pytest.raises(MbnInputError, match=r"^num_generations:"):
        minimize(sphere, jax.random.key(0), DEConfig(num_dims=2), -1)


def test_config_is_hashable_with_per_gene_bounds_as_tuples() -> None:
    init_range = {"init_low": -1.0, "init_high": 1.0}
    a = DEConfig(num_dims=3, lower=np.array([-1.0, -2.0, -3.0]), upper=[1, 2, 3], **init_range)
    b = DEConfig(num_dims=3, lower=(-1.0, -2.0, -3.0), upper=(1.0, 2.0, 3.0), **init_range)
    assert a == b and hash(a) == hash(b)
    assert a.lower == (-1.0, -2.0, -3.0) and isinstance(a.upper, tuple)
    c = DEConfig(num_dims=2, init_low=np.array([0.0, 1.0]), init_high=[2, 3])
    assert c.init_low == (0.0, 1.0) and c.init_high == (2.0, 3.0) and hash(c) is not None
