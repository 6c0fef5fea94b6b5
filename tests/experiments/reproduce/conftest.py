"""The quick run of ``mbn reproduce`` is ``tests/experiments/conftest.py``'s."""

from tests.experiments.conftest import reproduce

__all__ = ["reproduce"]
