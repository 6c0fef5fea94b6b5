"""Stage ``im``: the interpreter of RF with the connections that differ between RF and LF
programmable (paper section 2, eq. 2), and the RF and LF programs."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mbn.controllers import save_controller
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.pipeline.results import Record
from mbn.experiments.stages.common import MADE_BY, interpreter_of, read_network
from mbn.experiments.stages.keys import KEYS
from mbn.experiments.stages.multiplier import MultiplierStage
from mbn.experiments.stages.settings import InterpreterSettings
from mbn.networks.multiplier import load_multiplier
from mbn.notation import connection_name, connection_names

__all__ = ["IMResult", "IMStage"]


@dataclass(frozen=True, kw_only=True)
class IMResult(Record):
    """What the ``im`` stage records (``stages/im.json``): the interpreter's programmable
    connections (and in the paper's notation), their weights' bounds, RF's and LF's programs,
    its size, its multipliers' size and time constant ratio, and its steps per robot step."""

    connections: list[str]
    connections_paper_notation: list[str]
    lower: list[float]
    upper: list[float]
    programs: dict[str, list[float]]
    neurons: int
    multiplier_neurons: int
    tau_ratio: float
    substeps: int


class IMStage(Stage[IMResult]):
    name = "im"
    key_id = KEYS["im"]
    outputs = ("controllers/im.json",)
    needs = ("multiplier", "rf", "lf")
    result = IMResult

    def run(self, ctx: StageContext) -> IMResult:
        rf, lf = read_network(ctx, "rf"), read_network(ctx, "lf")
        mul = load_multiplier(ctx.rundir.controller_file("multiplier"))
        spec = interpreter_of(
            ctx, rf, lf, mul, {"made_by": MADE_BY, "stage": "im", "seed": ctx.seed}
        )
        save_controller(ctx.rundir.controller_file("im"), spec)
        interp, programs = spec.interpreter, spec.programs
        return IMResult(
            connections=[str(c) for c in interp.connections],
            connections_paper_notation=[connection_name(c) for c in interp.connections],
            lower=np.asarray(interp.lower, dtype=float).tolist(),
            upper=np.asarray(interp.upper, dtype=float).tolist(),
            programs={r: list(p) for r, p in programs.items()},
            neurons=int(interp.num_neurons),
            multiplier_neurons=ctx.read(MultiplierStage).neurons,
            tau_ratio=ctx.section(InterpreterSettings).tau_ratio,
            substeps=spec.substeps,
        )

    def summary(self, data: IMResult) -> str:
        return f"programmable {connection_names(data.connections)}; {data.neurons} neurons"
