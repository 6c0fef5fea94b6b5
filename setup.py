"""Build hooks of mbn (the rest of its metadata is in pyproject.toml).

An installed mbn ships ``mbn-gymnasium.pth`` at the top of site-packages, so that
``gymnasium.make("mbn/PioneerMaze-v0")`` works without importing mbn first (Gymnasium 1.x has no
plugin entry points; ``src/_mbn_gymnasium.py`` says how, ``docs/gym.md`` why). Wheels get it
through ``build_py``; editable installs (``pip install -e .``) through ``editable_wheel``, which
writes it beside its own path file.
"""

from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.command.editable_wheel import editable_wheel

PTH = "mbn-gymnasium.pth"
SOURCE = Path(__file__).resolve().parent / "src" / PTH


class BuildPy(build_py):
    """``build_py`` that also puts the path file at the top of the wheel."""

    def run(self) -> None:
        super().run()
        self.copy_file(str(SOURCE), str(Path(self.build_lib) / PTH), preserve_mode=False)

    def get_outputs(self, include_bytecode: bool = True) -> list[str]:
        return [*super().get_outputs(include_bytecode), str(Path(self.build_lib) / PTH)]


class EditableWheel(editable_wheel):
    """``editable_wheel`` that also writes the path file into the editable wheel."""

    def _select_strategy(self, name, tag, build_lib):  # type: ignore[no-untyped-def]
        strategy = super()._select_strategy(name, tag, build_lib)
        return _WithPth(strategy)


class _WithPth:
    """An editable-install strategy that adds the path file to what it writes."""

    def __init__(self, strategy) -> None:  # type: ignore[no-untyped-def]
        self.strategy = strategy

    def __call__(self, wheel, files, mapping) -> None:  # type: ignore[no-untyped-def]
        self.strategy(wheel, files, mapping)
        wheel.writestr(PTH, SOURCE.read_text())

    def __enter__(self):  # type: ignore[no-untyped-def]
        self.strategy.__enter__()
        return self

    def __exit__(self, *exc) -> None:  # type: ignore[no-untyped-def]
        self.strategy.__exit__(*exc)


setup(cmdclass={"build_py": BuildPy, "editable_wheel": EditableWheel})
