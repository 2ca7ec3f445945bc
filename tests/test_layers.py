"""The floors of the project stay floors: richmat_addon.core <- torch_models <- batch <- bench.

A lower floor that imports a higher one (even lazily, inside a function) drags the
higher one's dependencies (bpy, torch, Blender-only modules) into places that must
run without them, and an import circle makes module order matter. Both are read
from the source with ``ast``, so nothing here imports the project.
"""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("richmat_addon", "torch_models", "batch")

# Module prefix -> import prefixes it must never name.
FORBIDDEN: dict[str, tuple[str, ...]] = {
    "richmat_addon.core": ("bpy", "torch", "richmat_addon.blender", "torch_models", "batch", "bench"),
    "torch_models": ("bpy", "richmat_addon.blender", "batch", "bench"),
    "batch": ("bench",),
}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _sources() -> dict[str, Path]:
    return {_module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def _imports(name: str, path: Path, known: set[str]) -> set[str]:
    """Every module ``name`` imports anywhere in its file; ``from pkg import mod`` names pkg.mod."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([node.module] if node.module else []))
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                found.add(sub if sub in known else base)
    return found


def _graph() -> dict[str, set[str]]:
    sources = _sources()
    known = set(sources)
    return {name: _imports(name, path, known) for name, path in sources.items()}


def _within(module: str, prefix: str) -> bool:
    return module == prefix or module.startswith(prefix + ".")


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan), over project modules only."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v] & graph.keys():
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_graph_sees_every_package_and_resolves_relative_imports() -> None:
    graph = _graph()
    assert {"richmat_addon.core.enhance", "torch_models.generator.corpus", "batch.pipeline"} <= graph.keys()
    assert "richmat_addon.core.masks" in graph["richmat_addon.core.enhance"]  # `from . import masks`


def test_no_import_cycle() -> None:
    assert _cycles(_graph()) == []


def test_lower_floors_never_import_higher_ones() -> None:
    offences = [f"{module} imports {target}"
                for module, targets in _graph().items()
                for floor, banned in FORBIDDEN.items() if _within(module, floor)
                for target in sorted(targets) for prefix in banned if _within(target, prefix)]
    assert offences == []
