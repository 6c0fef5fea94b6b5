"""Controller files and controllers ready to run (``docs/controllers.md``).

* :mod:`mbn.controllers.spec` — what a file holds (three kinds), validated objects;
* :mod:`mbn.controllers.codec` — the JSON form: the only code that knows the file format;
* :mod:`mbn.controllers.load` — a spec made ready to run (:class:`LoadedController`).
"""

from mbn.controllers.codec import (
    controller_from_dict,
    controller_to_dict,
    read_controller_spec,
    save_controller,
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
    KINDS,
    ControllerSpec,
    CTRNNControllerSpec,
    InterpreterControllerSpec,
    MBNControllerSpec,
    PMInitial,
)

__all__ = [
    "KINDS",
    "KIND_CTRNN",
    "KIND_INTERPRETER",
    "KIND_MBN",
    "CTRNNControllerSpec",
    "ControllerSpec",
    "InterpreterControllerSpec",
    "LoadedController",
    "MBNControllerSpec",
    "PMInitial",
    "check_step",
    "check_trial_length",
    "controller_from_dict",
    "controller_to_dict",
    "load_controller",
    "make_controller",
    "read_controller_spec",
    "save_controller",
    "step_beyond_limit",
]
