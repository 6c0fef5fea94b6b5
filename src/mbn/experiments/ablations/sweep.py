"""``mbn sweep`` of the ablations: no per-run target; each ablation's success over the runs."""

from __future__ import annotations

from mbn.experiments.sweep.specs import (
    CONTROLLER_DE_STAGES,
    SweepSpec,
    controller_curve,
    loader,
)

__all__ = ["ABLATIONS_SPEC"]

#: The ablations of ``mbn run ablations`` (``AblationsSettings.variants``' default, in order;
#: named here so that a sweep's report imports no experiment).
_ABLATIONS = (
    "as_run",
    "wrong_program",
    "frozen_program",
    "exact_products",
    "tau_5",
    "tau_10",
    "tau_20",
    "tau_50",
    "mul3",
)
#: The ablations that change the interpreter (its trials with RF's and LF's programs too).
_ABLATIONS_IM = ("as_run", "exact_products", "tau_5", "tau_10", "tau_20", "tau_50", "mul3")

ABLATIONS_SPEC = SweepSpec(
    name="ablations",
    title="mbn sweep: ablations of the program path, over seeds",
    command="mbn run ablations",
    targets=(),
    tests=(
        *(f"{v}_mbn{x}" for v in _ABLATIONS for x in ("_jitter", "_heldout")),
        *(f"{v}_im_{net}_jitter" for v in _ABLATIONS_IM for net in ("rf", "lf")),
    ),
    groups=(
        ("MBN, jittered starts", tuple(f"{v}_mbn_jitter" for v in _ABLATIONS)),
        ("MBN, held-out maze", tuple(f"{v}_mbn_heldout" for v in _ABLATIONS)),
        ("IM with RF's program, jittered", tuple(f"{v}_im_rf_jitter" for v in _ABLATIONS_IM)),
        ("IM with LF's program, jittered", tuple(f"{v}_im_lf_jitter" for v in _ABLATIONS_IM)),
    ),
    targets_text="No ablation has a per-run target: each is measured over the runs "
    "(`docs/ablations.md`). `V_mbn_*` is the MBN with ablation V on the test maze's jittered "
    "starts and on the held-out maze; `V_im_rf_jitter` and `V_im_lf_jitter` the interpreter "
    "of ablation V with RF's and LF's program, where V changes it.",
    de_stages=CONTROLLER_DE_STAGES,
    curve=controller_curve,
    load=loader("ablations"),
)
