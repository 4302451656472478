"""Content hash of a stage's code, so that Snakemake reruns a stage when its code changes.

A rule passes ``code_hash("dexlite_pipeline.stages.<stage>")`` as a param. The hash covers
the named modules and every ``dexlite_pipeline`` module they import, directly or through
other modules (found statically from the source, so nothing is imported), plus the
``__init__`` of each package on the way. It hashes the parsed syntax tree, not the text:
comments and formatting do not trigger reruns, any change of behaviour does.

``python -m dexlite_pipeline.codehash --markdown`` prints each stage's closure as the
Markdown list in docs/design.md ("Code hashes"); a test holds the two to each other.
"""

from __future__ import annotations

import argparse
import ast
import hashlib
import importlib.util
import pkgutil
from functools import lru_cache
from pathlib import Path

PACKAGE = "dexlite_pipeline"


def package_root() -> Path:
    """Directory of the installed (or PYTHONPATH-first) ``dexlite_pipeline`` package."""
    spec = importlib.util.find_spec(PACKAGE)
    if spec is None or not spec.submodule_search_locations:
        raise ModuleNotFoundError(f"package {PACKAGE} not found")
    return Path(list(spec.submodule_search_locations)[0])


def module_file(name: str, root: Path) -> Path | None:
    """Source file of module ``name`` (dotted, starting with the package name), or None."""
    parts = name.split(".")
    if parts[0] != PACKAGE:
        return None
    base = root.joinpath(*parts[1:])
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def _imported_names(tree: ast.AST, module: str, is_package: bool) -> set[str]:
    """Absolute names of everything ``module`` imports, including ``from X import y`` as X.y."""
    names: set[str] = set()
    package_parts = module.split(".") if is_package else module.split(".")[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = package_parts[: len(package_parts) - node.level + 1]
                base = ".".join(anchor + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            names.add(base)
            names.update(f"{base}.{alias.name}" for alias in node.names)
    return names


def _with_parents(name: str) -> list[str]:
    parts = name.split(".")
    return [".".join(parts[: i + 1]) for i in range(len(parts))]


@lru_cache(maxsize=None)
def _parsed(path: Path, mtime_ns: int, size: int, name: str) -> tuple[str, frozenset[str]]:
    """(syntax tree dump, imported names) of one file; cached per file version."""
    tree = ast.parse(path.read_text(), filename=str(path))
    return ast.dump(tree), frozenset(_imported_names(tree, name, path.name == "__init__.py"))


def _parse(path: Path, name: str) -> tuple[str, frozenset[str]]:
    stat = path.stat()
    return _parsed(path, stat.st_mtime_ns, stat.st_size, name)


def module_closure(*modules: str, root: Path | None = None) -> dict[str, Path]:
    """Every package module reachable by imports from ``modules`` (with parent packages): name -> file."""
    root = package_root() if root is None else root
    for requested in modules:
        if module_file(requested, root) is None:
            raise ModuleNotFoundError(f"{requested}: no such module under {root}")
    found: dict[str, Path] = {}
    pending = [parent for m in modules for parent in _with_parents(m)]
    while pending:
        name = pending.pop()
        if name in found:
            continue
        path = module_file(name, root)
        if path is None:
            continue
        found[name] = path
        for imported in _parse(path, name)[1]:
            pending.extend(p for p in _with_parents(imported) if p.startswith(PACKAGE) and p not in found)
    return dict(sorted(found.items()))


def code_hash(*modules: str, root: Path | None = None) -> str:
    """Short hex digest of the syntax trees of ``modules`` and their package-internal imports."""
    if not modules:
        raise ValueError("code_hash: name at least one module")
    digest = hashlib.sha256()
    for name, path in module_closure(*modules, root=root).items():
        digest.update(f"{name}\0{_parse(path, name)[0]}\0".encode())
    return digest.hexdigest()[:16]


def stage_modules(root: Path | None = None) -> list[str]:
    """Every stage module (``dexlite_pipeline.stages.<stage>``), sorted."""
    root = package_root() if root is None else root
    return sorted(f"{PACKAGE}.stages.{info.name}" for info in pkgutil.iter_modules([str(root / "stages")]))


def closure_markdown(root: Path | None = None) -> str:
    """Each stage's closure as Markdown: the config tree (``settings`` and what it imports) once,
    then one item per stage with its module count and the modules beyond that tree. Names are
    relative to ``dexlite_pipeline``; the ``__init__`` of each package on the way is in the count
    but not listed."""
    root = package_root() if root is None else root
    config_tree = module_closure(f"{PACKAGE}.settings", root=root)

    def listed(names) -> str:
        modules = [n for n in names if module_file(n, root).name != "__init__.py"]
        return ", ".join(f"`{n.removeprefix(PACKAGE + '.')}`" for n in modules)

    lines = [f"- config tree ({len(config_tree)} modules): {listed(config_tree)}"]
    for stage in stage_modules(root):
        closure = module_closure(stage, root=root)
        reads_config = f"{PACKAGE}.settings" in closure
        own = [n for n in closure if not (reads_config and n in config_tree)]
        prefix = "the config tree and " if reads_config else ""
        lines.append(f"- `{stage.removeprefix(PACKAGE + '.stages.')}` ({len(closure)} modules): {prefix}{listed(own)}")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m dexlite_pipeline.codehash", description=__doc__.splitlines()[0])
    parser.add_argument("--markdown", action="store_true", help="print each stage's closure as a Markdown list")
    args = parser.parse_args(argv)
    if args.markdown:
        print(closure_markdown(), end="")
    else:
        for stage in stage_modules():
            print(f"{stage.removeprefix(f'{PACKAGE}.stages.')} {code_hash(stage)} {len(module_closure(stage))}")


if __name__ == "__main__":
    main()
