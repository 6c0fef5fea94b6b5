"""``mbn``'s controller kinds, registered as any other (:mod:`mbn.controllers.kinds`): their
files are written and read by :mod:`mbn.controllers.codec`, run by the runners of
:mod:`mbn.controllers.load`.

* :data:`CTRNN_KIND` (``mbn.controller.ctrnn``): drawn as its network's ``W``, ``WE`` and
  biases; evolved as every weight and bias of its network (the template's time constants, gains
  and settings kept);
* :data:`INTERPRETER_KIND` (``mbn.controller.interpreter``): drawn as its original network and
  its programs (one row each); evolved as one program, named ``"evolved"`` (program search on the
  fixed interpreter);
* :data:`MBN_KIND` (``mbn.controller.mbn``): drawn as its interpreter's original network, its
  programs and its program module; not evolved through a kind (the ``pm`` stage evolves its
  program module, ``docs/reproduce.md``);
* :data:`SWITCHED_KIND` (``mbn.controller.switched``): the MBN's baselines, followers switched by
  the tiles; drawn as each network's ``W``, ``WE`` and biases; not evolved through a kind (its
  networks are followers evolved or decoded elsewhere).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from mbn.controllers.codec import (
    ctrnn_body,
    ctrnn_from_body,
    interpreter_body,
    interpreter_from_body,
    mbn_body,
    mbn_from_body,
    switched_body,
    switched_from_body,
)
from mbn.controllers.kinds import ControllerKind, Runner, register_controller_kind
from mbn.controllers.load import (
    ctrnn_runner,
    ctrnn_step_beyond_limit,
    interpreter_runner,
    mbn_runner,
    switched_runner,
    switched_step_beyond_limit,
)
from mbn.controllers.spec import (
    KIND_CTRNN,
    KIND_INTERPRETER,
    KIND_MBN,
    KIND_SWITCHED,
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    MBNControllerSpec,
    SwitchedControllerSpec,
)
from mbn.errors import MbnInputError
from mbn.networks.ctrnn import CTRNN, make_ctrnn
from mbn.world.sensors import NoiseConfig

__all__ = [
    "CTRNN_KIND",
    "INTERPRETER_KIND",
    "MBN_KIND",
    "SWITCHED_KIND",
    "CTRNNKind",
    "InterpreterKind",
    "MBNKind",
    "SwitchedKind",
]

#: The name a program evolved on the fixed interpreter is stored under.
EVOLVED_PROGRAM = "evolved"


def _network_weights(net: CTRNN, prefix: str = "") -> dict[str, np.ndarray]:
    return {
        f"{prefix}W": np.asarray(net.W, np.float64),
        f"{prefix}WE": np.asarray(net.WE, np.float64),
        f"{prefix}bias": np.asarray(net.bias, np.float64),
    }


def _interpreter_weights(spec: InterpreterControllerSpec) -> dict[str, np.ndarray]:
    interp = spec.interpreter
    n, m = interp.num_original, interp.num_data_inputs
    out = {
        "W (original neurons)": np.asarray(interp.net.W, np.float64)[:n, :n],
        "WE (data inputs)": np.asarray(interp.net.WE, np.float64)[:n, :m],
    }
    if spec.programs:
        out["programs"] = np.asarray(list(spec.programs.values()), np.float64)
    return out


class CTRNNKind(ControllerKind):
    """``mbn.controller.ctrnn``: a CTRNN fed I1..I3 (and, with tile rules, the camera)."""

    name = KIND_CTRNN
    spec_type = CTRNNControllerSpec

    def to_dict(self, spec: Any) -> dict[str, Any]:
        return ctrnn_body(spec)

    def from_dict(self, data: dict[str, Any], where: str) -> Any:
        return ctrnn_from_body(data, where)

    def runner(
        self, spec: Any, program: str | None, noise: NoiseConfig | None, where: str
    ) -> Runner:
        return ctrnn_runner(spec, program, noise, where)

    def step_beyond_limit(self, spec: Any, where: str) -> str | None:
        return ctrnn_step_beyond_limit(spec, where)

    def weights(self, spec: Any) -> Mapping[str, np.ndarray]:
        return _network_weights(spec.net)

    def genes(self, spec: Any) -> np.ndarray:
        """``W`` (row-major), then ``WE`` (row-major), then the biases."""
        return np.concatenate([a.ravel() for a in _network_weights(spec.net).values()])

    def with_genes(self, spec: Any, genes: np.ndarray) -> Any:
        net: CTRNN = spec.net
        n, m = net.num_neurons, net.num_inputs
        values = np.asarray(genes)
        if values.shape != (n * n + n * m + n,):
            raise MbnInputError(
                f"{self.name}: a genome of this network is {n * n + n * m + n} genes, got shape "
                f"{values.shape}"
            )
        W = values[: n * n].reshape(n, n)
        WE = values[n * n : n * n + n * m].reshape(n, m)
        bias = values[n * n + n * m :]
        new = make_ctrnn(
            W, WE, np.asarray(net.tau), bias=bias, gain=np.asarray(net.gain), dtype=net.dtype
        )
        return dataclasses.replace(spec, net=new)


class InterpreterKind(ControllerKind):
    """``mbn.controller.interpreter``: the fixed-weight interpreter and its named programs."""

    name = KIND_INTERPRETER
    spec_type = InterpreterControllerSpec

    def to_dict(self, spec: Any) -> dict[str, Any]:
        return interpreter_body(spec)

    def from_dict(self, data: dict[str, Any], where: str) -> Any:
        return interpreter_from_body(data, where)

    def runner(
        self, spec: Any, program: str | None, noise: NoiseConfig | None, where: str
    ) -> Runner:
        return interpreter_runner(spec, program, noise, where)

    def weights(self, spec: Any) -> Mapping[str, np.ndarray]:
        return _interpreter_weights(spec)

    def genes(self, spec: Any) -> np.ndarray:
        """One program: the ``"evolved"`` one if the spec has it, else its first."""
        programs = spec.programs
        name = EVOLVED_PROGRAM if EVOLVED_PROGRAM in programs else next(iter(programs), None)
        if name is None:
            return np.full(len(spec.interpreter.connections), 0.5)
        return np.asarray(programs[name], np.float64)

    def with_genes(self, spec: Any, genes: np.ndarray) -> Any:
        """The interpreter with the program ``genes`` (clipped to [0, 1]) as its only one,
        named ``"evolved"``."""
        program = np.clip(np.asarray(genes, np.float64), 0.0, 1.0)
        return dataclasses.replace(spec, programs={EVOLVED_PROGRAM: program.tolist()})


class MBNKind(ControllerKind):
    """``mbn.controller.mbn``: a program module setting the interpreter's program."""

    name = KIND_MBN
    spec_type = MBNControllerSpec

    def to_dict(self, spec: Any) -> dict[str, Any]:
        return mbn_body(spec)

    def from_dict(self, data: dict[str, Any], where: str) -> Any:
        return mbn_from_body(data, where)

    def runner(
        self, spec: Any, program: str | None, noise: NoiseConfig | None, where: str
    ) -> Runner:
        return mbn_runner(spec, program, noise, where)

    def weights(self, spec: Any) -> Mapping[str, np.ndarray]:
        pm = _network_weights(spec.program_module, "program module ")
        return {**_interpreter_weights(spec.interpreter_spec), **pm}


class SwitchedKind(ControllerKind):
    """``mbn.controller.switched``: followers switched by the tiles (weights swapped, or a gate)."""

    name = KIND_SWITCHED
    spec_type = SwitchedControllerSpec

    def to_dict(self, spec: Any) -> dict[str, Any]:
        return switched_body(spec)

    def from_dict(self, data: dict[str, Any], where: str) -> Any:
        return switched_from_body(data, where)

    def runner(
        self, spec: Any, program: str | None, noise: NoiseConfig | None, where: str
    ) -> Runner:
        return switched_runner(spec, program, noise, where)

    def step_beyond_limit(self, spec: Any, where: str) -> str | None:
        return switched_step_beyond_limit(spec, where)

    def weights(self, spec: Any) -> Mapping[str, np.ndarray]:
        out: dict[str, np.ndarray] = {}
        for rule, net in spec.networks.items():
            out.update(_network_weights(net, f"{rule} "))
        return out


CTRNN_KIND = register_controller_kind(CTRNNKind())
INTERPRETER_KIND = register_controller_kind(InterpreterKind())
MBN_KIND = register_controller_kind(MBNKind())
SWITCHED_KIND = register_controller_kind(SwitchedKind())
