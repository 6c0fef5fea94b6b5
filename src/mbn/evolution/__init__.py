"""Evolutionary optimisers for the network weights.

:mod:`mbn.evolution.de` implements Differential Evolution (DE/best/1/bin) with generation-based
ask/tell over explicit state and PRNG keys, as used by the paper (section 3.1).
"""

from mbn.evolution.de import (
    BOUNDS_POLICIES,
    MIN_POPSIZE,
    BoundsPolicy,
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
