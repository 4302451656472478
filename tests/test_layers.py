"""The package's import structure: which modules import which, read from the source (no import runs).

Every import counts, at module level or inside a function (a lazy import, or one under
``TYPE_CHECKING``, is still a dependency). No two modules import each other, directly or through
others; no two packages do either; and every package sits in a layer of ``LAYERS`` and imports
only from its own layer or lower ones. docs/design.md's "Import structure" is generated from here:
``PYTHONPATH=src python tests/test_layers.py docs/design.md``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import dexlite_pipeline

PACKAGE_DIR = Path(dexlite_pipeline.__file__).parent
DESIGN_DOC = Path(__file__).resolve().parents[1] / "docs" / "design.md"
MARKERS = ("<!-- import structure: start -->\n", "<!-- import structure: end -->")

# The layers, lowest first: a package imports only packages of its own layer or lower ones.
# Packages are the second dotted component (``io`` for ``dexlite_pipeline.io.grasp_store``); a
# top-level module is its own package (``tabletop``), the package's ``__init__`` is ``dexlite_pipeline``.
LAYERS = (
    ("helpers", ("dexlite_pipeline", "atomic", "codehash", "config", "device", "parallel", "progress", "sharding")),
    ("hand", ("hand",)),
    ("objects", ("objects",)),
    ("io", ("io",)),  # the DexGraspNet importer builds object assets
    ("tabletop", ("tabletop",)),  # support planes (numbers, no hand); the hand's depth below one is energy.table_clearance
    ("energy", ("energy",)),
    ("sim", ("sim",)),
    ("curation", ("curation",)),
    ("model", ("model",)),  # trainer reads curation's origin labels
    ("optim", ("optim",)),  # post-optimization refines the model's samples (model.methods)
    ("evaluation", ("evaluation",)),
    ("dataset", ("dataset",)),  # the grasp dataset kept in the repository: distinct labels from evaluation.diversity
    ("loop", ("loop",)),  # the data loop's rounds: sampling, refinement, checks and training of the components below
    ("evaluator", ("evaluator",)),  # the learned evaluator in the pipeline: on-generator examples (a round's steps), training, ranking
    ("settings", ("settings", "config_files")),  # the typed config tree over every component's config module; the files written from it
    ("report", ("report",)),
    ("stages and tools", ("stages", "tools")),
    ("api", ("api",)),  # dexlite_pipeline.api.grasp: the grasp tool as a function
    ("commands", ("commands",)),
    ("cli", ("cli",)),
)


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


def package_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """Package -> the other packages its modules import."""
    packages: dict[str, set[str]] = {}
    for module, imported in graph.items():
        packages.setdefault(_package(module), set()).update(_package(b) for b in imported if _package(b) != _package(module))
    return packages


def layer_of() -> dict[str, int]:
    """Package -> the index of its layer in ``LAYERS``."""
    return {package: index for index, (_, packages) in enumerate(LAYERS) for package in packages}


def upward_imports(graph: dict[str, set[str]], layers: dict[str, int]) -> list[str]:
    """Every import of a module from a higher layer than its own, as 'a -> b (layer of a < layer of b)'."""
    names = [name for name, _ in LAYERS]
    return sorted(
        f"{a} -> {b} ({names[layers[_package(a)]]} imports {names[layers[_package(b)]]})"
        for a, imported in graph.items()
        for b in imported
        if layers[_package(a)] < layers[_package(b)]
    )


def import_structure_markdown() -> str:
    """docs/design.md's "Import structure": one row per package, lowest layer first, with what it imports."""
    packages = package_graph(import_graph())
    layers = layer_of()
    rows = ["| layer | packages | import |", "| --- | --- | --- |"]
    for index, (name, members) in enumerate(LAYERS):
        alike: dict[tuple[str, ...], list[str]] = {}  # members of a layer that import the same packages share a row
        for package in members:
            alike.setdefault(tuple(sorted(packages.get(package, ()), key=lambda p: (layers[p], p))), []).append(package)
        for imported, group in alike.items():
            shown = ", ".join(f"`{p}`" for p in imported) or "nothing"
            rows.append(f"| {index + 1} {name} | {', '.join(f'`{p}`' for p in group)} | {shown} |")
    return "\n".join(rows) + "\n"


def _doc_parts(text: str) -> tuple[str, str, str]:
    start, end = MARKERS
    head, rest = text.split(start, 1)
    listed, tail = rest.split(end, 1)
    return head, listed, tail


def test_the_graph_sees_imports_at_module_level_and_in_functions():
    graph = import_graph()
    assert "dexlite_pipeline.objects.build" in graph["dexlite_pipeline.io.dexgraspnet"]  # inside a function
    assert "dexlite_pipeline.atomic" in graph["dexlite_pipeline.io.grasp_store"]  # at module level
    assert "dexlite_pipeline.hand.model" in graph["dexlite_pipeline.hand"]  # a package's re-export
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == {frozenset("abc")}


def test_no_file_level_cycle():
    found = [sorted(c) for c in cycles(import_graph())]
    assert not found, f"modules that import each other (directly or through others): {found}"


def test_no_package_cycle():
    found = [sorted(c) for c in cycles(package_graph(import_graph()))]
    assert not found, f"packages that import each other (directly or through others): {found}"


def test_every_package_has_one_layer():
    placed = [package for _, members in LAYERS for package in members]
    assert len(placed) == len(set(placed)), "a package is in two layers"
    unplaced = sorted(set(package_graph(import_graph())) - set(placed))
    assert not unplaced, f"packages not in LAYERS (add each to its layer): {unplaced}"


def test_no_module_imports_a_higher_layer():
    offending = upward_imports(import_graph(), layer_of())
    assert not offending, "imports from a lower layer up to a higher one:\n" + "\n".join(offending)


def test_upward_imports_are_found():
    graph = {"dexlite_pipeline.energy.terms": {"dexlite_pipeline.sim.lift"}, "dexlite_pipeline.sim.lift": {"dexlite_pipeline.energy.terms"}}
    assert upward_imports(graph, layer_of()) == ["dexlite_pipeline.energy.terms -> dexlite_pipeline.sim.lift (energy imports sim)"]


def test_design_doc_shows_the_import_structure():
    text = DESIGN_DOC.read_text()
    assert all(marker in text for marker in MARKERS), "docs/design.md lost its import structure markers"
    assert _doc_parts(text)[1] == import_structure_markdown(), (
        "docs/design.md's import structure is stale: run PYTHONPATH=src python tests/test_layers.py docs/design.md"
    )


if __name__ == "__main__":
    import sys

    path = Path(sys.argv[1]) if len(sys.argv) > 1 else DESIGN_DOC
    head, _, tail = _doc_parts(path.read_text())
    path.write_text(head + MARKERS[0] + import_structure_markdown() + MARKERS[1] + tail)
    print("regenerated", path)
