"""Controller files and controllers ready to run (``docs/controllers.md``).

* :mod:`mbn.controllers.spec` — what a file of ``mbn``'s kinds holds, validated objects;
* :mod:`mbn.controllers.kinds` — what a kind of controller provides to be saved, loaded,
  evaluated, drawn and evolved (:class:`ControllerKind`), and the one registry of kinds
  (:func:`register_controller_kind`; ``docs/architecture.md``, "Adding a controller kind");
* :mod:`mbn.controllers.codec` — the JSON form: the only code that knows the file format;
* :mod:`mbn.controllers.load` — a spec made ready to run (:class:`LoadedController`);
* :mod:`mbn.controllers.builtin` — ``mbn``'s kinds, registered as any other (imported
  here, so that they are registered whenever a controller is read, written or run).
"""

from mbn.controllers import builtin as builtin
from mbn.controllers.codec import (
    controller_from_dict,
    controller_to_dict,
    read_controller_spec,
    save_controller,
)
from mbn.controllers.kinds import (
    ControllerKind,
    Runner,
    check_body,
    controller_kind,
    kind_of,
    register_controller_kind,
    registered_kinds,
    unregister_controller_kind,
)
from mbn.controllers.load import (
    LoadedController,
    check_step,
    check_trial_length,
    load_controller,
    make_controller,
    step_beyond_limit,
)
from mbn.controllers.spec import (
    KIND_CTRNN,
    KIND_INTERPRETER,
    KIND_MBN,
    KIND_SWITCHED,
    KINDS,
    ControllerSpec,
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    MBNControllerSpec,
    PMInitial,
    SwitchedControllerSpec,
    decoded_networks,
    switched_from_mbn,
)

__all__ = [
    "KINDS",
    "KIND_CTRNN",
    "KIND_INTERPRETER",
    "KIND_MBN",
    "KIND_SWITCHED",
    "CTRNNControllerSpec",
    "ControllerKind",
    "ControllerSpec",
    "InterpreterControllerSpec",
    "LoadedController",
    "MBNControllerSpec",
    "PMInitial",
    "Runner",
    "SwitchedControllerSpec",
    "check_body",
    "check_step",
    "check_trial_length",
    "controller_from_dict",
    "controller_kind",
    "controller_to_dict",
    "decoded_networks",
    "kind_of",
    "load_controller",
    "make_controller",
    "read_controller_spec",
    "register_controller_kind",
    "registered_kinds",
    "save_controller",
    "step_beyond_limit",
    "switched_from_mbn",
    "unregister_controller_kind",
]
