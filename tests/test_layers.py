"""The package's import structure: which modules import which, read from the source (no import runs).

Every import counts, at module level or inside a function (a lazy import is still a dependency).
`io` sits above `objects` (the DexGraspNet importer builds object assets); `objects` imports
nothing from `io`, and no two modules import each other, directly or through others.
"""

from __future__ import annotations

import ast
from pathlib import Path

import dexlite_pipeline

PACKAGE_DIR = Path(dexlite_pipeline.__file__).parent


def _module_files() -> dict[str, Path]:
    files = {}
    for path in PACKAGE_DIR.rglob("*.py"):
        parts = path.relative_to(PACKAGE_DIR.parent).with_suffix("").parts
        files[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return files


def import_graph() -> dict[str, set[str]]:
    """Module name -> the package modules it imports (``from X import y`` counts as X.y when y is a module)."""
    files = _module_files()
    graph = {}
    for name, path in files.items():
        package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        imported = set()
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                candidates = [[alias.name] for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = ".".join(package[: len(package) - node.level + 1] + [node.module or ""]).strip(".") if node.level else node.module
                candidates = [[f"{base}.{alias.name}", base] for alias in node.names]
            else:
                continue
            imported.update(next((c for c in options if c in files), None) for options in candidates)
        graph[name] = imported - {None, name}
    return graph


def cycles(graph: dict[str, set[str]]) -> set[frozenset[str]]:
    """The strongly connected components of more than one node (Tarjan), each a set of nodes."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: set[frozenset[str]] = set()

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for successor in graph.get(node, ()):
            if successor not in index:
                visit(successor)
                low[node] = min(low[node], low[successor])
            elif successor in stack:
                low[node] = min(low[node], index[successor])
        if low[node] == index[node]:
            component = set()
            while True:
                member = stack.pop()
                component.add(member)
                if member == node:
                    break
            if len(component) > 1:
                found.add(frozenset(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def _package(module: str) -> str:
    """``dexlite_pipeline.io.grasp_store`` -> ``io``; a top-level module is its own package."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def _edges_between(graph: dict[str, set[str]], source: str, target: str) -> list[str]:
    return sorted(f"{a} -> {b}" for a, imported in graph.items() for b in imported if _package(a) == source and _package(b) == target)


def test_the_graph_sees_imports_at_module_level_and_in_functions():
    graph = import_graph()
    assert "dexlite_pipeline.objects.build" in graph["dexlite_pipeline.io.dexgraspnet"]  # inside a function
    assert "dexlite_pipeline.atomic" in graph["dexlite_pipeline.io.grasp_store"]  # at module level
    assert "dexlite_pipeline.hand.model" in graph["dexlite_pipeline.hand"]  # a package's re-export
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == {frozenset("abc")}


def test_io_and_objects_import_one_way():
    graph = import_graph()
    assert _edges_between(graph, "io", "objects"), "io.dexgraspnet builds object assets: the graph should see it"
    assert not _edges_between(graph, "objects", "io"), f"objects imports io: {_edges_between(graph, 'objects', 'io')}"


def test_io_and_objects_are_in_no_package_cycle():
    graph = import_graph()
    packages = {}
    for module, imported in graph.items():
        packages.setdefault(_package(module), set()).update(_package(b) for b in imported if _package(b) != _package(module))
    tangled = [sorted(c) for c in cycles(packages) if {"io", "objects"} & c]
    assert not tangled, f"packages that import each other, directly or through others: {tangled}"


def test_no_file_level_cycle():
    found = [sorted(c) for c in cycles(import_graph())]
    assert not found, f"modules that import each other (directly or through others): {found}"
