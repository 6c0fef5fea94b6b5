"""The ``mbn`` command line: one module per command group (``networks``, ``world``,
``evaluate``, ``reproduce``), each adding its sub-parsers with ``set_defaults(func=...,
precision=...)``; :func:`main` parses, runs the command in its precision
(:func:`mbn.precision.scope`) and turns every bad input into one line and exit status 2.

Every subcommand validates its input; a bad input prints one line ``mbn: error: ...`` naming what
is wrong (file and line where there is one) and exits with status 2. Files are written atomically.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from mbn import __version__
from mbn.cli import evaluate, networks, reproduce, world
from mbn.errors import MbnInputError
from mbn.precision import scope

__all__ = ["EXIT_BAD_INPUT", "build_parser", "main"]

EXIT_BAD_INPUT = 2


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors and exit status 2 (as argparse itself uses)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``mbn`` (exposed for documentation and tests)."""
    parser = _Parser(
        prog="mbn",
        description="Programmable fixed-weight CTRNNs and the Multiple Behavior Network "
        "(Montone, Donnarumma & Prevete, ICANNGA 2011).",
        epilog="examples:\n" + networks.EPILOG + world.EPILOG + reproduce.EPILOG + evaluate.EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"mbn {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    networks.add_commands(sub, _Parser)
    world.add_commands(sub, _Parser)
    evaluate.add_commands(sub, _Parser)
    reproduce.add_commands(sub, _Parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``mbn`` command; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        with scope(args.precision):
            return int(args.func(args))
    except MbnInputError as exc:
        print(f"mbn: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("mbn: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
