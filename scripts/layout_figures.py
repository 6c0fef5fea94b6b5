"""Figures of the package's layout, for a tree of ``src/mbn`` (this checkout's, or an older
commit's in a git worktree), as ``docs/architecture.md`` reports them:

- **import circles**: strongly connected groups of modules (lazy imports inside functions
  count; a package's ``__init__`` re-exporting its own children does not), as
  ``tests/test_architecture.py`` finds them;
- **arrows back up**: imports from a layer to one above it (the layers of
  ``docs/architecture.md``: ``mbn`` (the package face) > ``cli`` > ``experiments`` > ``viz`` >
  ``controllers`` > ``control`` > ``world``, ``networks`` > ``evolution`` > the base modules);
- **the largest experiment module**: lines of the largest module of an experiment's own package
  (``experiments/NAME/``: not the stage library, the pipeline or the sweep);
- **string look-ups of settings**: ``ctx.section("name")`` and ``config["name"]``;
- **string look-ups of stage results**: ``ctx.read("name")`` and ``read_stage("name")``
  outside the pipeline's serialisation (``pipeline/``), and subscripts with a string
  (``stages["tests"]["agreement"]``, ``.get("key")``) in the code of the claims, reports and
  sweep targets (found in the syntax tree: a docstring or a list literal does not count);
- **``dict[str, Any]`` annotations** in ``src/mbn``.

    python scripts/layout_figures.py [SRC] [--json out.json]   # SRC: default src/mbn
"""

from __future__ import annotations

import argparse
import ast
import json
import re
import sys
from pathlib import Path

TOP = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(TOP))

from tests.test_architecture import cycles, import_graph  # noqa: E402

#: Layers, top first; a module not listed is a base module (config, io, paper, errors, ...).
LAYERS = (
    ("mbn",),
    ("mbn.cli",),
    ("mbn.experiments",),
    ("mbn.viz",),
    ("mbn.controllers",),
    ("mbn.control",),
    ("mbn.world", "mbn.networks"),
    ("mbn.evolution",),
)


def layer(module: str) -> int:
    """The module's layer: 0 the package face, larger below; the base modules last."""
    if module in ("mbn", "mbn.__main__"):  # the package face and ``python -m mbn``
        return 0
    for rank, prefixes in enumerate(LAYERS[1:], start=1):
        if any(module == p or module.startswith(p + ".") for p in prefixes):
            return rank
    return len(LAYERS)


def back_arrows(graph: dict[str, set[str]]) -> list[str]:
    """``a -> b`` for every import from a lower layer to a higher one."""
    return sorted(f"{a} -> {b}" for a, deps in graph.items() for b in deps if layer(b) < layer(a))


def _experiment_modules(src: Path) -> list[Path]:
    shared = {"stages", "pipeline", "sweep"}
    root = src / "experiments"
    return [
        p
        for d in sorted(root.iterdir())
        if d.is_dir() and d.name not in shared and not d.name.startswith("_")
        for p in sorted(d.rglob("*.py"))
    ]


_SECTION = re.compile(
    r"""\.section\(\s*["'][a-z_0-9]+["']\s*\)|config\[\s*["'][a-z_0-9]+["']\s*\]"""
)
_READ = re.compile(r"""(?:ctx\.read|\.read_stage)\(\s*["'][a-z_0-9]+["']\s*\)""")


def string_subscripts(text: str) -> list[tuple[int, str]]:
    """``(line, key)`` of every subscript by a string constant (``x["key"]``) and every
    ``.get("key", ...)`` in the code of ``text``."""
    found = []
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Subscript):
            key = node.slice
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "get"
            and node.args
        ):
            key = node.args[0]
        else:
            continue
        if isinstance(key, ast.Constant) and isinstance(key.value, str):
            found.append((node.lineno, key.value))
    return found


def _reader_files(src: Path) -> list[Path]:
    """The claims, reports and sweep targets: where stage results are read."""
    ex = src / "experiments"
    files = sorted(ex.glob("*/claims.py")) + sorted(ex.glob("*/report.py"))
    files += [ex / "sweep" / "targets.py"]
    return [f for f in files if f.exists()]


def figures(src: Path) -> dict[str, object]:
    graph = import_graph(src)
    for name in graph:
        graph[name] = {d for d in graph[name] if not d.startswith(name + ".")}
    sizes = {
        str(p.relative_to(src)): len(p.read_text().splitlines()) for p in _experiment_modules(src)
    }
    largest = max(sizes, key=lambda k: sizes[k])
    files = sorted(src.rglob("*.py"))
    outside_pipeline = [f for f in files if "pipeline" not in f.relative_to(src).parts]
    return {
        "import_circles": len(cycles(graph)),
        "back_arrows": back_arrows(graph),
        "largest_experiment_module": {"module": largest, "lines": sizes[largest]},
        "settings_string_lookups": sum(len(_SECTION.findall(f.read_text())) for f in files),
        "result_reads_by_name": sum(len(_READ.findall(f.read_text())) for f in outside_pipeline),
        "result_string_subscripts": sum(
            len(string_subscripts(f.read_text())) for f in _reader_files(src)
        ),
        "dict_str_any_annotations": sum(f.read_text().count("dict[str, Any]") for f in files),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("src", nargs="?", default=str(TOP / "src" / "mbn"))
    parser.add_argument("--json", help="also write the figures there")
    args = parser.parse_args()
    out = figures(Path(args.src).resolve())
    text = json.dumps(out, indent=1)
    print(text)
    if args.json:
        Path(args.json).write_text(text + "\n")


if __name__ == "__main__":
    main()
