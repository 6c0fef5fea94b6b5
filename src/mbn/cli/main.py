"""The ``mbn`` command line: one module per command group (``networks``, ``world``,
``evaluate``, ``reproduce``, ``sweep``), each adding its sub-parsers with ``set_defaults(func=...,
precision=..., writes=...)``; :func:`main` imports a lab's extension modules
(:mod:`mbn.extensions`), parses, checks that an output file can be written before any work,
turns the persistent compilation cache on (:mod:`mbn.compile_cache`), runs the command in its
precision (:func:`mbn.precision.scope`) and turns every bad input and every system error into
one line and exit status 2.

Every subcommand validates its input; a bad input prints one line ``mbn: error: ...`` naming what
is wrong (file and line where there is one) and exits with status 2. Files are written atomically.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Sequence
from typing import TextIO

from mbn import compile_cache, extensions
from mbn._version import __version__
from mbn.cli import evaluate, networks, reproduce, run, sweep, world
from mbn.errors import MbnInputError, MbnWarning
from mbn.io import check_writable
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
        epilog="examples:\n"
        + networks.EPILOG
        + world.EPILOG
        + reproduce.EPILOG
        + sweep.EPILOG
        + run.EPILOG
        + evaluate.EPILOG
        + "\nhow long a run takes: README, Set-up.\n",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"mbn {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    networks.add_commands(sub, _Parser)
    world.add_commands(sub, _Parser)
    evaluate.add_commands(sub, _Parser)
    reproduce.add_commands(sub, _Parser)
    sweep.add_commands(sub, _Parser)
    run.add_commands(sub, _Parser)
    return parser


def _show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    """Warnings of mbn as one line ``mbn: warning: ...``; those of NumPy and JAX (overflow in an
    intermediate, a dtype note) are not the user's to act on and are not shown."""
    if issubclass(category, MbnWarning):
        print(f"mbn: warning: {message}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``mbn`` command; returns the exit status."""
    try:
        extensions.load()  # a lab's registered rules, families, ... (before --help lists them)
    except MbnInputError as exc:
        print(f"mbn: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    args = build_parser().parse_args(argv)
    try:
        if getattr(args, "writes", None) == "file":
            check_writable(args.out)  # before any long work
        compile_cache.enable()
        with warnings.catch_warnings(), scope(args.precision):
            warnings.showwarning = _show_warning
            return int(args.func(args))
    except MbnInputError as exc:
        print(f"mbn: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as exc:  # a system error no reader or writer named: still one line
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"mbn: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("mbn: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
