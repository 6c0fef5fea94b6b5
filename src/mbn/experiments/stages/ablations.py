"""Stage ``ablations``: the MBN with parts of its program path changed, one at a time — the
wrong program (the tiles swapped), the program frozen at its value before the first tile, the
multipliers replaced by exact products, the multipliers' time constant at τ/5, τ/10 (the
paper's), τ/20 and τ/50 (sub-steps keeping h / τ_m = 0.1), and the paper's 3-neuron multiplier
in place of the run's — each on the jittered test maze and the held-out one, with the
interpreter's agreement with RF and LF where the interpreter changes."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax.numpy as jnp
import numpy as np
from jax import Array

from mbn.config import Settings, setting
from mbn.control.ctrnn import NETWORK_SUBSTEPS, CTRNNState, ctrnn_controller
from mbn.controllers import (
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    LoadedController,
    MBNControllerSpec,
    make_controller,
    read_controller_spec,
)
from mbn.errors import MbnInputError
from mbn.experiments.evolve import Genome
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.pipeline.results import Record, optional
from mbn.experiments.stages.keys import KEYS
from mbn.experiments.stages.protocol import test_specs
from mbn.experiments.stages.records import RateRecord, TrialCounts
from mbn.experiments.stages.settings import InterpreterSettings
from mbn.experiments.stages.tests import TestsSettings
from mbn.experiments.trials import TrialGroup, rate_record, run_trial_groups
from mbn.experiments.trials import agreement as same_exits
from mbn.networks.ctrnn import CTRNN, euler_steps, firing_rate
from mbn.networks.multiplier import Multiplier, load_default, load_multiplier
from mbn.networks.programmable import Programmable, build_interpreter
from mbn.world.mazes.load import load_maze
from mbn.world.rollout import Shared

__all__ = [
    "VARIANTS",
    "AblationsResult",
    "AblationsSettings",
    "AblationsStage",
    "InterpreterRan",
    "Variant",
]

_DOC = "docs/ablations.md"

#: The ablations, in the order of the table: name -> what it changes.
VARIANTS = {
    "as_run": "the run's MBN (no change)",
    "wrong_program": "the tiles swapped: a one-colour tile sends LF's program, two colours RF's",
    "frozen_program": "the program frozen at its value before the first tile",
    "exact_products": "the multipliers replaced by exact products (the program decoded into the "
    "network's weights each step)",
    "tau_5": "multipliers at τ/5 (10 sub-steps)",
    "tau_10": "multipliers at τ/10, the paper's (20 sub-steps)",
    "tau_20": "multipliers at τ/20 (40 sub-steps)",
    "tau_50": "multipliers at τ/50 (100 sub-steps)",
    "mul3": "the paper's 3-neuron multiplier in place of the run's",
}
#: Time-constant ratios of the ``tau_*`` variants.
_TAUS = {"tau_5": 0.2, "tau_10": 0.1, "tau_20": 0.05, "tau_50": 0.02}


@dataclass(frozen=True)
class AblationsSettings(Settings):
    """The ablations run and the trials of each."""

    section = "ablations"
    variants: tuple[str, ...] = setting(
        tuple(VARIANTS), doc="the ablations run", choices=tuple(VARIANTS), source=_DOC
    )
    jitter_per_mark: int = setting(
        20, doc="jittered trials per start mark of the test maze", low=1, high=1000, source=_DOC
    )
    heldout_repeats: int = setting(
        17, doc="trials per start mark of the held-out maze", low=1, high=1000, source=_DOC
    )


class _ExactState(NamedTuple):
    pm: CTRNN | Shared
    pm_y: Array
    y: Array


def _exact_mbn(spec: MBNControllerSpec, rf: CTRNN) -> tuple[Callable[..., Any], Any]:
    """The MBN with its interpreter's multipliers replaced by exact products: each step the
    PM's program is decoded (eq. 2) into the programmable weights of RF's network, which is
    integrated as a plain 3-neuron CTRNN (the followers' sub-steps)."""
    im = spec.interpreter_spec
    interp, pm = im.interpreter, spec.program_module
    if spec.readout is not None:
        raise MbnInputError("ablations: an MBN with a readout is not the paper's")
    genome = Genome.around(rf, interp.connections)
    index = jnp.asarray(spec.program_neurons, jnp.int32)
    h = im.dt / spec.pm_substeps
    inner = ctrnn_controller(dt=im.dt, substeps=NETWORK_SUBSTEPS, motor=im.motor)

    def control(state: _ExactState, obs: Any) -> tuple[_ExactState, tuple[Array, Array]]:
        net = state.pm
        assert isinstance(net, CTRNN)
        camera = jnp.stack([obs.camera == t for t in range(1, net.WE.shape[-1] + 1)], axis=-1)
        pm_y = euler_steps(net, state.pm_y, camera.astype(state.pm_y.dtype), h, spec.pm_substeps)
        program = firing_rate(net, pm_y)[..., index]
        W, WE = genome.weights(jnp.asarray(interp.decode(program.astype(rf.W.dtype))))
        decoded = dataclasses.replace(rf, W=W, WE=WE)
        new, vw = inner(CTRNNState(decoded, state.y), obs)
        return _ExactState(state.pm, pm_y, new.y), vw

    y0 = (
        jnp.zeros((pm.num_neurons,), pm.dtype)
        if spec.initial is None
        else jnp.asarray(spec.initial.potentials, pm.dtype)
    )

    def initial(n: int) -> _ExactState:
        return _ExactState(
            Shared(pm),
            jnp.broadcast_to(y0, (n, pm.num_neurons)),
            jnp.zeros((n, rf.num_neurons), rf.dtype),
        )

    return control, initial


def _swapped(spec: MBNControllerSpec) -> MBNControllerSpec:
    """The MBN whose program module reads a one-colour tile as two colours and back."""
    pm = spec.program_module
    WE = np.asarray(pm.WE, dtype=float).copy()
    WE[:, [0, 1]] = WE[:, [1, 0]]
    return dataclasses.replace(
        spec, program_module=dataclasses.replace(pm, WE=jnp.asarray(WE, pm.dtype))
    )


def _frozen(spec: MBNControllerSpec) -> InterpreterControllerSpec:
    """The interpreter running, throughout, the program the PM sends before its first tile."""
    pm = spec.program_module
    y0 = np.zeros(pm.num_neurons) if spec.initial is None else np.asarray(spec.initial.potentials)
    program = np.asarray(firing_rate(pm, jnp.asarray(y0, pm.dtype)), float)[
        list(spec.program_neurons)
    ]
    return dataclasses.replace(spec.interpreter_spec, programs={"frozen": program.tolist()})


def _rebuilt(
    im: InterpreterControllerSpec, rf: CTRNN, multiplier: Multiplier, tau_ratio: float
) -> InterpreterControllerSpec:
    """The interpreter of RF with the same programmable connections and bounds, ``multiplier``
    in every connection at ``tau_ratio`` of the receiving neuron's time constant, with the
    sub-steps that keep h / tau_m = 0.1 (the multipliers' training step)."""
    interp = im.interpreter
    lower, upper = np.asarray(interp.lower, float), np.asarray(interp.upper, float)
    programmable = [
        Programmable(c, float(lo), float(hi))
        for c, lo, hi in zip(interp.connections, lower, upper, strict=True)
    ]
    rebuilt = build_interpreter(rf, programmable, multiplier, tau_ratio=tau_ratio)
    tau = float(np.min(np.asarray(rf.tau)))
    substeps = max(1, round(im.dt / (0.1 * tau_ratio * tau)))
    return dataclasses.replace(im, interpreter=rebuilt, substeps=substeps)


def _agreements(
    ims: dict[str, dict[str, np.ndarray]], nets: dict[str, dict[str, np.ndarray]]
) -> dict[str, float]:
    """How often the interpreter with RF's (LF's) program took RF's (LF's) exits on the same
    trials, jittered and held out."""
    return {
        f"{net}{x}": same_exits(ims[f"im_{net}{x}"], nets[f"{net}{x}"])["rate"]
        for net in ("rf", "lf")
        for x in ("_jitter", "_heldout")
    }


@dataclass(frozen=True, kw_only=True)
class InterpreterRan(Record):
    """The interpreter a variant ran with: its multipliers' time constant ratio, sub-steps and
    multiplier size."""

    tau_ratio: float
    substeps: int
    multiplier_neurons: int


@dataclass(frozen=True, kw_only=True)
class Variant(Record):
    """One ablation: what it changed, the MBN's jittered and held-out trials, and, where the
    interpreter changed, the interpreter it ran, its agreement with RF and LF (``rf_jitter``,
    ``lf_jitter``, ``rf_heldout``, ``lf_heldout``) and its own trials with each program."""

    what: str
    mbn_jitter: RateRecord
    mbn_heldout: RateRecord
    interpreter: InterpreterRan | None = optional()
    agreement: dict[str, float] | None = optional()
    im_rf_jitter: RateRecord | None = optional()
    im_lf_jitter: RateRecord | None = optional()


@dataclass(frozen=True, kw_only=True)
class AblationsResult(Record):
    """What the ``ablations`` stage records (``stages/ablations.json``): each variant of the
    MBN's program path with its success, the networks' own success, and the trials per test."""

    variants: dict[str, Variant]
    networks: dict[str, RateRecord]
    trials: TrialCounts


class AblationsStage(Stage[AblationsResult]):
    name = "ablations"
    key_id = KEYS["ablations"]
    needs = ("rf", "lf", "im", "pm")
    settings = AblationsSettings

    result = AblationsResult

    def run(self, ctx: StageContext) -> AblationsResult:
        s: AblationsSettings = ctx.settings
        tests = ctx.section(TestsSettings)
        mazes = [load_maze(tests.maze), load_maze(tests.heldout_maze)]
        ctl = ctx.rundir.controller_file
        rf_spec, lf_spec = read_controller_spec(ctl("rf")), read_controller_spec(ctl("lf"))
        im, mbn = read_controller_spec(ctl("im")), read_controller_spec(ctl("mbn"))
        if not isinstance(im, InterpreterControllerSpec) or not isinstance(mbn, MBNControllerSpec):
            raise MbnInputError("ablations: controllers/im.json or mbn.json is not the run's")
        if not isinstance(rf_spec, CTRNNControllerSpec) or not isinstance(
            lf_spec, CTRNNControllerSpec
        ):
            raise MbnInputError("ablations: controllers/rf.json or lf.json is not a CTRNN")
        rf = rf_spec.net

        def run(
            loaded: dict[str, tuple[LoadedController, str, str | None]], seconds: float
        ) -> dict[str, dict[str, np.ndarray]]:
            """Each controller's jittered and held-out trials (one rollout: one function)."""
            groups = []
            first = next(iter(loaded.values()))[0]
            for name, (c, behavior, initial) in loaded.items():
                ran = test_specs(
                    behavior,
                    seconds=seconds,
                    jitter_per_mark=s.jitter_per_mark,
                    heldout_repeats=s.heldout_repeats,
                    test_seed=ctx.seeds["test_jitter"],
                    heldout_seed=ctx.seeds["heldout_jitter"],
                    initial=initial,
                )
                groups += [
                    TrialGroup(f"{name}{x}", 1 if x == "_heldout" else 0, ran[x], c.initial_state)
                    for x in ("_jitter", "_heldout")
                ]
            verdicts, _, _, _ = run_trial_groups(
                mazes,
                groups,
                first.controller,
                seconds=seconds,
                dt=first.dt,
                sensors=first.sensors,
                camera=mbn.camera,
                until_judged=True,
            )
            return verdicts

        initial = mbn.initial.rule if mbn.initial is not None else None
        run_ratio = ctx.section(InterpreterSettings).tau_ratio
        run_multiplier = load_multiplier(ctl("multiplier"))
        ratios: dict[str, float] = {"as_run": run_ratio}
        nets = run(
            {
                "rf": (make_controller(rf_spec, where="rf"), "right", None),
                "lf": (make_controller(lf_spec, where="lf"), "left", None),
            },
            tests.seconds,
        )
        rows: dict[str, Any] = {}
        bar = ctx.progress.task("ablations", len(s.variants))
        for v, variant in enumerate(s.variants):
            ctx.progress.update(bar, completed=v, info=variant)
            interp_spec: InterpreterControllerSpec | None = None
            if variant == "as_run":
                loaded_mbn = make_controller(mbn, where=variant)
                interp_spec = im
            elif variant == "wrong_program":
                loaded_mbn = make_controller(_swapped(mbn), where=variant)
            elif variant == "frozen_program":
                loaded_mbn = make_controller(_frozen(mbn), "frozen", where=variant)
            elif variant == "exact_products":
                control, start = _exact_mbn(mbn, rf)
                base = make_controller(mbn, where=variant)
                loaded_mbn = dataclasses.replace(base, controller=control, initial_state=start)
            else:
                ratio = _TAUS.get(variant, run_ratio)
                multiplier = load_default(3) if variant == "mul3" else run_multiplier
                interp_spec = _rebuilt(im, rf, multiplier, ratio)
                ratios[variant] = ratio
                loaded_mbn = make_controller(
                    dataclasses.replace(mbn, interpreter_spec=interp_spec), where=variant
                )
            out = run({"mbn": (loaded_mbn, "tiles", initial)}, tests.mbn_seconds)
            row: dict[str, Any] = {
                "what": VARIANTS[variant],
                "mbn_jitter": rate_record(out["mbn_jitter"]),
                "mbn_heldout": rate_record(out["mbn_heldout"]),
            }
            if variant == "exact_products":
                # the interpreter by exact products is the network each program decodes to
                genome = Genome.around(rf, im.interpreter.connections)
                decoded = {
                    net: CTRNNControllerSpec(
                        net=genome.network(im.interpreter.decode(jnp.asarray(im.programs[rule])))
                    )
                    for net, rule in (("rf", "right"), ("lf", "left"))
                }
                ims = run(
                    {
                        f"im_{net}": (make_controller(spec, where=variant), rule, None)
                        for (net, spec), rule in zip(
                            decoded.items(), ("right", "left"), strict=True
                        )
                    },
                    tests.seconds,
                )
                row["agreement"] = _agreements(ims, nets)
                row["im_rf_jitter"] = rate_record(ims["im_rf_jitter"])
                row["im_lf_jitter"] = rate_record(ims["im_lf_jitter"])
            if interp_spec is not None:
                ims = run(
                    {
                        "im_rf": (
                            make_controller(interp_spec, "right", where=variant),
                            "right",
                            None,
                        ),
                        "im_lf": (
                            make_controller(interp_spec, "left", where=variant),
                            "left",
                            None,
                        ),
                    },
                    tests.seconds,
                )
                row["interpreter"] = {
                    "tau_ratio": float(ratios[variant]),
                    "substeps": int(interp_spec.substeps),
                    "multiplier_neurons": int(interp_spec.interpreter.mul_size),
                }
                row["agreement"] = _agreements(ims, nets)
                row["im_rf_jitter"] = rate_record(ims["im_rf_jitter"])
                row["im_lf_jitter"] = rate_record(ims["im_lf_jitter"])
            rows[variant] = row
            ctx.progress.update(bar, completed=v + 1, info=variant)
        return AblationsResult.from_json(
            {
                "variants": rows,
                "networks": {name: rate_record(nets[name]) for name in nets},
                "trials": {
                    "jitter_per_mark": s.jitter_per_mark,
                    "heldout_repeats": s.heldout_repeats,
                },
            }
        )

    def summary(self, result: AblationsResult) -> str:
        return ", ".join(f"{v} {r.mbn_jitter.rate:.0%}" for v, r in result.variants.items())
