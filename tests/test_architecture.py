"""The house rules of the package layout, checked on the source (``docs/architecture.md``): no
import circle anywhere in ``src/mbn`` (lazy imports inside functions count too), no private name
imported across modules, matplotlib only in ``mbn.viz``, the file codecs only where they belong."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "mbn"


def _module_name(path: Path, src: Path = SRC) -> str:
    rel = path.relative_to(src.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules(src: Path = SRC) -> dict[str, Path]:
    return {_module_name(p, src): p for p in src.rglob("*.py")}


def _imports(path: Path) -> list[tuple[str, list[str], bool]]:
    """``(module, names, type_checking_only)`` of every import in a file."""
    tree = ast.parse(path.read_text())
    guarded: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for sub in ast.walk(node):
                guarded.add(id(sub))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append((node.module, [a.name for a in node.names], id(node) in guarded))
        elif isinstance(node, ast.Import):
            out += [(a.name, [], id(node) in guarded) for a in node.names]
    return out


def import_graph(src: Path = SRC) -> dict[str, set[str]]:
    """``module -> the modules it imports`` in the package at ``src`` (lazy imports inside
    functions included, imports under ``TYPE_CHECKING`` left out); also used by
    ``scripts/layout_figures.py`` on older trees."""
    modules = _modules(src)
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for name, path in modules.items():
        for target, names, type_only in _imports(path):
            if type_only or not target.startswith("mbn"):
                continue
            # ``from mbn.x import y`` imports the module mbn.x.y when y is one
            deps = [f"{target}.{n}" for n in names if f"{target}.{n}" in modules] or [target]
            for dep in deps:
                while dep not in modules and "." in dep:
                    dep = dep.rsplit(".", 1)[0]
                if dep in modules and dep != name:
                    graph[name].add(dep)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_circle_in_the_package():
    graph = import_graph()
    # a package's __init__ re-exporting its own submodules is not a circle of design: leave
    # the edges from a package to its children out
    for name in graph:
        graph[name] = {d for d in graph[name] if not d.startswith(name + ".")}
    assert cycles(graph) == []


def test_no_private_name_is_imported_across_modules():
    offenders = [
        f"{_module_name(path)} imports {name} from {target}"
        for path in SRC.rglob("*.py")
        for target, names, _ in _imports(path)
        if target.startswith("mbn")
        for name in names
        if name.startswith("_") and not name.startswith("__")
    ]
    assert offenders == []


@pytest.mark.parametrize(
    ("what", "allowed"),
    [
        ("matplotlib", ("mbn.viz",)),
        ("mbn.controllers.codec", ("mbn.controllers",)),
        ("mbn.world.mazes.grid_text", ("mbn.world.mazes",)),
        ("mbn.world.mazes.toml_maze", ("mbn.world.mazes.load",)),
        ("mbn.world.mazes.stage", ("mbn.world.mazes.load",)),
    ],
)
def test_a_dependency_stays_in_its_room(what, allowed):
    users = sorted(
        name
        for name, path in _modules().items()
        for target, _, _ in _imports(path)
        if (target == what or target.startswith(what + "."))
        and not name.startswith(allowed)
        and name != what
    )
    assert users == [], f"{what} is imported outside {allowed}: {users}"


def test_the_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []
