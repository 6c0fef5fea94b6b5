"""Registers mbn's Gymnasium environment (``mbn/PioneerMaze-v0``) when Gymnasium is imported.

Gymnasium 1.x has no plugin entry points, so ``gymnasium.make("mbn/PioneerMaze-v0")`` would need
``import mbn.world.gym_env`` first. An installed ``mbn`` ships ``mbn-gymnasium.pth``, which
imports this module when Python starts: it only puts a finder on ``sys.meta_path`` (nothing else
is imported, Gymnasium included). When a program imports ``gymnasium``, the finder steps aside,
lets Gymnasium load as usual and then registers the environment by its entry point string, so
that ``mbn.world.gym_env`` (and JAX) are imported only by ``gymnasium.make``. Any failure here
leaves Gymnasium as it would be without ``mbn``; see ``docs/gym.md``.
"""

import sys  # and nothing else at start-up (contextlib alone would cost milliseconds)

ENV_ID = "mbn/PioneerMaze-v0"
ENTRY_POINT = "mbn.world.gym_env:PioneerMazeEnv"


def register(gymnasium):  # type: ignore[no-untyped-def]
    """Register the environment with the ``gymnasium`` module given (idempotent)."""
    if ENV_ID not in gymnasium.registry:
        gymnasium.register(id=ENV_ID, entry_point=ENTRY_POINT)


class _Finder:
    """Waits for ``gymnasium`` to be imported, then registers the environment once."""

    def find_spec(self, name, path=None, target=None):  # type: ignore[no-untyped-def]
        if name != "gymnasium":
            return None
        try:  # noqa: SIM105
            sys.meta_path.remove(self)
        except ValueError:
            pass
        try:
            import importlib.util

            spec = importlib.util.find_spec(name)
        except Exception:
            return None
        loader = getattr(spec, "loader", None)
        if loader is None or not hasattr(loader, "exec_module"):
            return spec
        load = loader.exec_module

        def exec_module(module):  # type: ignore[no-untyped-def]
            load(module)
            try:  # noqa: SIM105
                register(module)
            except Exception:  # Gymnasium without register or registry: leave it be
                pass

        loader.exec_module = exec_module
        return spec


def install():  # type: ignore[no-untyped-def]
    """Register now if Gymnasium is loaded, else wait for its import (once a process)."""
    gymnasium = sys.modules.get("gymnasium")
    if gymnasium is not None:
        try:  # noqa: SIM105
            register(gymnasium)
        except Exception:
            pass
    elif not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder())


install()
