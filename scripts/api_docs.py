"""The API reference of mbn's stable surface, built from the docstrings by pdoc (HTML, one page
per module, searchable).

    pip install -e '.[docs]'
    python scripts/api_docs.py --out build/api      # then open build/api/index.html

The modules are those of the names ``help(mbn)`` lists (``mbn.__all__``), with the modules a lab
extends ``mbn`` through (the experiment registry, the pipeline, the stage library's key table,
the sweep's view, the settings). Any warning pdoc gives fails the build (exit 1, the warnings
listed), except the one of a known pdoc bug: a ``typing.NamedTuple``'s generated ``__init__``
whose annotations are postponed (``from __future__ import annotations``) cannot be resolved
(mitmproxy/pdoc issue 765); its fields are documented all the same.
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
import warnings
from pathlib import Path

#: Modules documented beyond those of ``mbn.__all__``: where a lab extends mbn.
EXTENSION_MODULES = (
    "mbn.experiments.registry",
    "mbn.experiments.pipeline",
    "mbn.experiments.stages",
    "mbn.experiments.sweep.specs",
    "mbn.config",
)

#: pdoc's message for a NamedTuple's ``__init__`` (mitmproxy/pdoc issue 765).
_NAMEDTUPLE_BUG = re.compile(
    r"^Error parsing type annotation .* for (?P<cls>mbn(\.\w+)+)\.__init__\. Import of \w+ failed"
)


def modules() -> list[str]:
    """``mbn`` and the module of every name it exports, then :data:`EXTENSION_MODULES`."""
    import mbn

    found = ["mbn"]
    for name in mbn.__all__:
        if name == "__version__":
            continue
        module = getattr(mbn, name).__module__
        if module not in found:
            found.append(module)
    found += [m for m in EXTENSION_MODULES if m not in found]
    return found


def _is_namedtuple_bug(message: str) -> bool:
    match = _NAMEDTUPLE_BUG.match(message)
    if match is None:
        return False
    module, _, name = match["cls"].rpartition(".")
    try:
        cls = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError):
        return False
    return isinstance(cls, type) and issubclass(cls, tuple) and hasattr(cls, "_fields")


def build(out: Path) -> list[str]:
    """Write the reference into ``out``; the warnings pdoc gave (none for a clean build)."""
    import pdoc

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pdoc.pdoc(*modules(), output_directory=out)
    messages = []
    for w in caught:
        text = str(w.message)
        # a ResourceWarning is the garbage collector's word on a file some other code of the
        # process left open (a test run before this one), never pdoc's on a docstring
        if issubclass(w.category, ResourceWarning):
            continue
        if not _is_namedtuple_bug(text) and text not in messages:
            messages.append(text)
    return messages


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("build/api"), help="output folder")
    args = parser.parse_args(argv)
    try:
        import pdoc  # noqa: F401
    except ImportError:
        print("api_docs: pdoc is not installed (pip install -e '.[docs]')", file=sys.stderr)
        return 2
    problems = build(args.out)
    for text in problems:
        print(f"api_docs: warning: {text}", file=sys.stderr)
    if problems:
        return 1
    print(f"api_docs: {len(modules())} modules, {args.out / 'index.html'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
