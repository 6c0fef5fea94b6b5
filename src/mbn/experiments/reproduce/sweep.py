"""``mbn sweep`` of the reproduction: its per-run targets, the tests its report tabulates and the
DE curves it draws."""

from __future__ import annotations

from mbn.experiments.stages.protocol import TEST_NAMES
from mbn.experiments.sweep.specs import (
    CONTROLLER_DE_STAGES,
    FOLLOWERS,
    SweepSpec,
    by_trials,
    controller_curve,
    loader,
)
from mbn.experiments.sweep.targets import GENERALIZATION_TARGETS, TARGETS

__all__ = ["REPRODUCE_SPEC"]

REPRODUCE_SPEC = SweepSpec(
    name="reproduce",
    title="mbn sweep: the reproduction over seeds",
    command="mbn reproduce",
    targets=TARGETS,
    generalization=GENERALIZATION_TARGETS,
    tests=tuple(TEST_NAMES),
    groups=by_trials("Paper protocol", FOLLOWERS),
    targets_text="The targets (`mbn.experiments.sweep.targets`): the paper protocol in every "
    "trial for RF, LF, the IM with each program and the MBN; at least 95 % on the jittered "
    "starts and on the held-out maze for each; the interpreter takes its network's exits in at "
    "least 98 % of the jittered trials. The published weights have no target.",
    de_stages=CONTROLLER_DE_STAGES,
    curve=controller_curve,
    load=loader("reproduce"),
)
