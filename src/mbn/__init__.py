"""mbn: programmable fixed-weight CTRNNs and the Multiple Behavior Network.

A reproduction of Montone, Donnarumma & Prevete (ICANNGA 2011) as a reusable library. The names
below are the stable surface a researcher uses; each is imported from its module on first use, so
``import mbn`` costs nothing (no JAX import, no side effect). The layers and the glossary of the
paper's symbols are in ``docs/architecture.md``.

Networks (paper section 2): :class:`CTRNN`, :func:`make_ctrnn`, :func:`simulate`,
:func:`firing_rate`; the multiplier: :class:`Multiplier`, :func:`load_multiplier`,
:func:`load_default_multiplier`, :func:`multiply`; interpreters: :class:`Connection`,
:func:`differing_connections`, :func:`build_interpreter`, :func:`run_interpreter`,
:func:`run_network`; the published matrices: :func:`published_rf`, :func:`published_lf`.

The robot (section 3): :func:`load_maze`, :class:`Maze`, :func:`rollout`, :class:`RolloutConfig`,
:func:`load_controller`, :class:`TrialSpec`, :func:`run_trials`.

Evolution: :class:`DEConfig`. Experiments: :data:`REPRODUCE`, :func:`run_experiment`.
Precision: :func:`precision_scope`.

Your own experiment (``docs/architecture.md``, "Your own experiment"): :class:`Experiment`, a
composition of :class:`Stage` objects (a :class:`StageRegistry` of them), each reading its
:class:`Settings` (fields made by :func:`setting`) through a :class:`StageContext`;
:func:`register` adds it to the experiments ``mbn run`` and ``mbn sweep`` know, and a
:class:`SweepSpec` gives its sweep's per-run targets; a stage's result is a :class:`Record`.
Your own sensor, controller kind, maze family, rule and maze format (``docs/architecture.md``,
"Adding a ..."): :func:`register_sensor`, :func:`register_controller_kind`,
:func:`register_family`, :func:`register_rule`, :func:`register_format`.

The API reference of these names and their modules is built from the docstrings by
``python scripts/api_docs.py --out build/api`` (pdoc; ``pip install -e '.[docs]'``).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from mbn._version import __version__

if TYPE_CHECKING:
    from mbn.config import Settings, setting
    from mbn.controllers.kinds import register_controller_kind
    from mbn.controllers.load import load_controller
    from mbn.evolution.de import DEConfig
    from mbn.experiments.pipeline import Experiment, Record, Stage, StageContext
    from mbn.experiments.pipeline import Registry as StageRegistry
    from mbn.experiments.pipeline.runner import run_experiment
    from mbn.experiments.registry import register
    from mbn.experiments.reproduce import REPRODUCE
    from mbn.experiments.sweep.specs import SweepSpec
    from mbn.experiments.trials import TrialSpec, run_trials
    from mbn.networks.ctrnn import CTRNN, firing_rate, make_ctrnn, simulate
    from mbn.networks.multiplier import Multiplier, load_multiplier, multiply
    from mbn.networks.multiplier import load_default as load_default_multiplier
    from mbn.networks.programmable import (
        Connection,
        build_interpreter,
        differing_connections,
        run_network,
    )
    from mbn.networks.programmable import run as run_interpreter
    from mbn.paper import published_lf, published_rf
    from mbn.precision import scope as precision_scope
    from mbn.world.mazes.families import register_family
    from mbn.world.mazes.load import load_maze, register_format
    from mbn.world.mazes.model import Maze
    from mbn.world.rollout import RolloutConfig, rollout
    from mbn.world.rules import register_rule
    from mbn.world.senses import register_sensor

#: name -> (module, attribute)
_SURFACE = {
    "CTRNN": ("mbn.networks.ctrnn", "CTRNN"),
    "make_ctrnn": ("mbn.networks.ctrnn", "make_ctrnn"),
    "simulate": ("mbn.networks.ctrnn", "simulate"),
    "firing_rate": ("mbn.networks.ctrnn", "firing_rate"),
    "Multiplier": ("mbn.networks.multiplier", "Multiplier"),
    "load_multiplier": ("mbn.networks.multiplier", "load_multiplier"),
    "load_default_multiplier": ("mbn.networks.multiplier", "load_default"),
    "multiply": ("mbn.networks.multiplier", "multiply"),
    "Connection": ("mbn.networks.programmable", "Connection"),
    "differing_connections": ("mbn.networks.programmable", "differing_connections"),
    "build_interpreter": ("mbn.networks.programmable", "build_interpreter"),
    "run_interpreter": ("mbn.networks.programmable", "run"),
    "run_network": ("mbn.networks.programmable", "run_network"),
    "published_rf": ("mbn.paper", "published_rf"),
    "published_lf": ("mbn.paper", "published_lf"),
    "load_maze": ("mbn.world.mazes.load", "load_maze"),
    "Maze": ("mbn.world.mazes.model", "Maze"),
    "rollout": ("mbn.world.rollout", "rollout"),
    "RolloutConfig": ("mbn.world.rollout", "RolloutConfig"),
    "load_controller": ("mbn.controllers.load", "load_controller"),
    "TrialSpec": ("mbn.experiments.trials", "TrialSpec"),
    "run_trials": ("mbn.experiments.trials", "run_trials"),
    "DEConfig": ("mbn.evolution.de", "DEConfig"),
    "REPRODUCE": ("mbn.experiments.reproduce", "REPRODUCE"),
    "run_experiment": ("mbn.experiments.pipeline.runner", "run_experiment"),
    "precision_scope": ("mbn.precision", "scope"),
    "Experiment": ("mbn.experiments.pipeline.experiment", "Experiment"),
    "Stage": ("mbn.experiments.pipeline.registry", "Stage"),
    "StageRegistry": ("mbn.experiments.pipeline.registry", "Registry"),
    "StageContext": ("mbn.experiments.pipeline.context", "StageContext"),
    "Settings": ("mbn.config", "Settings"),
    "setting": ("mbn.config", "setting"),
    "register": ("mbn.experiments.registry", "register"),
    "SweepSpec": ("mbn.experiments.sweep.specs", "SweepSpec"),
    "Record": ("mbn.experiments.pipeline.results", "Record"),
    "register_sensor": ("mbn.world.senses", "register_sensor"),
    "register_controller_kind": ("mbn.controllers.kinds", "register_controller_kind"),
    "register_family": ("mbn.world.mazes.families", "register_family"),
    "register_rule": ("mbn.world.rules", "register_rule"),
    "register_format": ("mbn.world.mazes.load", "register_format"),
}

__all__ = [
    "CTRNN",
    "REPRODUCE",
    "Connection",
    "DEConfig",
    "Experiment",
    "Maze",
    "Multiplier",
    "Record",
    "RolloutConfig",
    "Settings",
    "Stage",
    "StageContext",
    "StageRegistry",
    "SweepSpec",
    "TrialSpec",
    "__version__",
    "build_interpreter",
    "differing_connections",
    "firing_rate",
    "load_controller",
    "load_default_multiplier",
    "load_maze",
    "load_multiplier",
    "make_ctrnn",
    "multiply",
    "precision_scope",
    "published_lf",
    "published_rf",
    "register",
    "register_controller_kind",
    "register_family",
    "register_format",
    "register_rule",
    "register_sensor",
    "rollout",
    "run_experiment",
    "run_interpreter",
    "run_network",
    "run_trials",
    "setting",
    "simulate",
]


def __getattr__(name: str) -> Any:
    if name in _SURFACE:
        module, attribute = _SURFACE[name]
        value = getattr(importlib.import_module(module), attribute)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'mbn' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
