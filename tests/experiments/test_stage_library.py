"""The stage library (``mbn.experiments.stages``): every stage's random-stream number comes from
one table, and the experiments compose from the library without importing one another."""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
from pathlib import Path

import mbn.experiments.stages as library
from mbn.experiments.pipeline import Stage
from mbn.experiments.registry import registered
from mbn.experiments.stages.keys import KEYS, OWN_KEYS_FROM

EXPERIMENTS = Path(library.__file__).parent.parent
#: The packages that are experiments (a composition of stages and a report each).
EXPERIMENT_PACKAGES = ("reproduce", "behaviours", "noise", "ablations", "contest")


def _library_stages() -> list[tuple[str, type[Stage]]]:
    found = []
    for info in pkgutil.iter_modules(library.__path__):
        module = importlib.import_module(f"{library.__name__}.{info.name}")
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if (
                issubclass(cls, Stage)
                and cls.__module__ == module.__name__
                and not inspect.isabstract(cls)
                and cls.key_id != 0  # a base the stages of a module share (no stream)
            ):
                found.append((info.name, cls))
    return found


def test_every_stage_of_the_library_takes_its_number_from_the_table():
    stages = _library_stages()
    assert len(stages) >= len(KEYS)
    for module, cls in stages:
        # a module of one stage is its key; a module of several keys each as MODULE.STAGE
        several = sum(m == module for m, _ in stages) > 1
        key = f"{module}.{cls.name}" if several else module
        assert cls.key_id == KEYS[key], (module, cls.__name__)
    assert len(set(KEYS.values())) == len(KEYS)
    assert all(1 <= k < OWN_KEYS_FROM for k in KEYS.values())
    # every number of the table is a stage's
    assert {cls.key_id for _, cls in stages} == set(KEYS.values())


def test_the_registered_experiments_run_stages_of_the_library():
    for name, registration in registered().items():
        for stage in registration.load().registry:
            assert type(stage).__module__.startswith(library.__name__ + "."), (name, stage.name)


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
        elif isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
    return names


def test_no_experiment_imports_another_and_the_library_and_platform_import_none():
    for package in EXPERIMENT_PACKAGES:
        others = [f"mbn.experiments.{p}" for p in EXPERIMENT_PACKAGES if p != package]
        for path in (EXPERIMENTS / package).rglob("*.py"):
            for name in _imports(path):
                assert not any(name == o or name.startswith(o + ".") for o in others), (
                    f"{path.relative_to(EXPERIMENTS)} imports {name}"
                )
    every = [f"mbn.experiments.{p}" for p in EXPERIMENT_PACKAGES]
    platform = [*(EXPERIMENTS / "stages").rglob("*.py"), *(EXPERIMENTS / "pipeline").rglob("*.py")]
    platform += [*(EXPERIMENTS / "sweep").rglob("*.py"), EXPERIMENTS / "registry.py"]
    for path in platform:
        for name in _imports(path):
            assert not any(name == o or name.startswith(o + ".") for o in every), (
                f"{path.relative_to(EXPERIMENTS)} imports {name}"
            )
