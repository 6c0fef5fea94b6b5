"""Stage ``multiplier``: the shipped multiplier (6 neurons by default) or one trained again."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

import jax
import numpy as np

from mbn.config import Locator, Settings, setting
from mbn.errors import MbnInputError
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.pipeline.results import Record, keyed, optional
from mbn.experiments.pipeline.runconfig import RunSettings
from mbn.experiments.stages.keys import KEYS
from mbn.networks.multiplier import (
    SHIPPED,
    dense_grid,
    evaluate,
    load_default,
    multiply,
    relative_errors,
    save_multiplier,
    shipped_metrics,
    training_pairs,
    validation_pairs,
)

__all__ = [
    "FixedPointCheck",
    "MultiplierGrid",
    "MultiplierMetrics",
    "MultiplierResult",
    "MultiplierSettings",
    "MultiplierStage",
    "PaperClaim",
    "RelativeErrors",
]

#: Points per axis of the error grid recorded for the report.
GRID_POINTS = 101
#: The paper's multiplier (section 2.1): 3 neurons.
PAPER_NEURONS = 3
#: Targets below this are left out of the "honest reading" of the paper's 5 % claim: the
#: relative error of any logistic output is unbounded as the target goes to 0.
RELATIVE_FLOOR = 0.05


@dataclass(frozen=True)
class MultiplierSettings(Settings):
    """The multiplier CTRNN that replaces each programmable connection (paper 2.1)."""

    section = "multiplier"
    neurons: int = setting(
        6,
        doc="neurons of the multiplier (shipped: 3 or 6; any size when retrained)",
        low=1,
        high=64,
        source="docs/multiplier.md (the paper's 3 neurons miss its 5 % claim; 6 meet it)",
    )
    retrain: bool = setting(
        False,
        doc="train the multiplier again by BPTT instead of using the shipped one",
        source="docs/multiplier.md",
    )

    def check_names(self, sections: Mapping[str, Settings], where: Locator) -> None:
        # checked here, not on construction: --retrain is applied after the settings file
        if not self.retrain and self.neurons not in SHIPPED:
            raise MbnInputError(
                f"{where(self.section, 'neurons')}: the shipped multipliers have "
                f"{' or '.join(map(str, sorted(SHIPPED)))} neurons, not {self.neurons}; set "
                "[multiplier] retrain = true (or pass --retrain) to train one"
            )


#: The record of the multiplier's output on the dense grid (``records/NAME.npz``).
GRID_RECORD = "multiplier_grid"


class MultiplierGrid(NamedTuple):
    """The multiplier's output on the dense grid of [0, 1]^2 (``records/multiplier_grid.npz``,
    one array per field): the grid's pairs and the outputs, for the report's error map."""

    grid: np.ndarray
    output: np.ndarray


@dataclass(frozen=True, kw_only=True)
class FixedPointCheck(Record):
    """The multiplier's output settled: how far it moves over a second settling time and with
    a finer step (:func:`~mbn.networks.multiplier.evaluate`)."""

    max_abs_diff_2T: float
    max_abs_diff_fine_step: float
    passed: bool


@dataclass(frozen=True, kw_only=True)
class MultiplierMetrics(Record):
    """The multiplier's errors (:func:`~mbn.networks.multiplier.evaluate`): on random pairs
    (relative error, and where the product is at least 0.05; absolute) and on a dense grid."""

    num_validation_pairs: int
    fraction_within_5pct: float
    max_rel_error: float
    max_rel_error_product_floor: float = keyed("max_rel_error_product_ge_0.05")
    max_abs_error_validation: float
    grid_points_per_axis: int
    max_abs_error_grid: float
    mean_abs_error_grid: float
    fixed_point: FixedPointCheck


@dataclass(frozen=True, kw_only=True)
class RelativeErrors(Record):
    """Relative errors on a set of pairs (:func:`~mbn.networks.multiplier.relative_errors`):
    how many, the least target kept (``floor``), the share within 5 %, the largest error and
    the pair where it is."""

    pairs: int
    floor: float
    min_target: float
    fraction_within_5pct: float
    max_rel_error: float
    worst: list[float]


@dataclass(frozen=True, kw_only=True)
class PaperClaim(Record):
    """The paper's 3-neuron multiplier checked against its 5 % claim: on 100 random pairs (the
    paper's test), on the paper's 10 x 10 training grid, and on a dense grid away from 0."""

    neurons: int
    source: str
    validation: RelativeErrors
    paper_grid: RelativeErrors
    dense_grid: RelativeErrors


@dataclass(frozen=True, kw_only=True)
class MultiplierResult(Record):
    """What the ``multiplier`` stage records (``stages/multiplier.json``): where the multiplier
    came from, its size, its errors on 100 random pairs and the dense grid (``metrics``), the
    paper's 3-neuron claim checked (``paper_claim``), and its errors on the paper's grid."""

    source: str
    neurons: int
    metrics: MultiplierMetrics
    paper_claim: PaperClaim | None = optional()  # None: a run from before it was recorded
    paper_grid: RelativeErrors | None = optional()


class MultiplierStage(Stage[MultiplierResult]):
    name = "multiplier"
    key_id = KEYS["multiplier"]
    outputs = ("controllers/multiplier.json", "records/multiplier_grid.npz")
    settings = MultiplierSettings
    result = MultiplierResult

    def run(self, ctx: StageContext) -> MultiplierResult:
        s: MultiplierSettings = ctx.settings
        n = s.neurons
        if s.retrain:
            from mbn.networks.multiplier_train import recipe, train_stages

            bar = ctx.progress.task(f"training the {n}-neuron multiplier", None)

            def report(done: int, total: int) -> None:
                ctx.progress.update(bar, completed=done, info="")

            mul, metrics = train_stages(ctx.key, recipe(n), progress=report)
            metrics["training"]["seed"] = ctx.seed
            source = "trained by this run"
        else:
            mul = load_default(n)
            metrics = shipped_metrics(n)
            source = f"shipped ({SHIPPED[n]})"
        precision = ctx.section(RunSettings).precision
        validation = validation_pairs(jax.random.fold_in(ctx.key, 1), 100)
        measured = evaluate(mul, validation, precision=precision)
        paper = mul if n == PAPER_NEURONS else load_default(PAPER_NEURONS)
        paper_claim = PaperClaim(
            neurons=PAPER_NEURONS,
            source=source if n == PAPER_NEURONS else f"shipped ({SHIPPED[PAPER_NEURONS]})",
            # the paper's test: 100 random pairs, every one within 5 % of its target
            validation=RelativeErrors.from_json(
                relative_errors(paper, validation, precision=precision)
            ),
            # the paper's own grid: its 100 training pairs, equally spaced in (0, 1)^2
            paper_grid=RelativeErrors.from_json(
                relative_errors(paper, training_pairs(), precision=precision)
            ),
            # the dense grid where the target is not near 0
            dense_grid=RelativeErrors.from_json(
                relative_errors(
                    paper, dense_grid(GRID_POINTS), floor=RELATIVE_FLOOR, precision=precision
                )
            ),
        )
        save_multiplier(ctx.rundir.controller_file("multiplier"), mul, metrics)
        grid = np.asarray(dense_grid(GRID_POINTS))
        output = np.asarray(multiply(mul, grid, precision=precision))
        ctx.rundir.save_record(GRID_RECORD, MultiplierGrid(grid=grid, output=output)._asdict())
        # the time constant it is embedded at is the interpreter's ([interpreter] tau_ratio,
        # recorded by stage im), not the multiplier's
        return MultiplierResult(
            source=source,
            neurons=n,
            metrics=MultiplierMetrics.from_json(measured),
            paper_claim=paper_claim,
            paper_grid=RelativeErrors.from_json(
                relative_errors(mul, training_pairs(), precision=precision)
            ),
        )

    def summary(self, data: MultiplierResult) -> str:
        grid = data.metrics.max_abs_error_grid
        return f"{data.source}, max |error| on the grid {grid:.4f}"
