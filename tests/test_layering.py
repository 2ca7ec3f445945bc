"""The import graph of the repository's Python, read from the source (every import, also inside functions):
no import cycles, no arrow from a lower floor to a higher one, and tests/ and bench/ never import each other
(what both need lives in support/); and what the farm's Blender side imports from torch_models imports without torch."""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("richmat_addon", "torch_models", "batch", "tools", "support", "bench", "tests")
# What each part may import besides itself: the add-on's core is the lowest floor (no bpy, no torch), the
# torch backend never reaches the bpy side, the farm sits on both, and the shared test support sits under
# the benches and the tests, which are two rooms that do not see each other. The formats and the clock the
# farm's Blender side shares with the backend sit on the core alone, below the rest of torch_models.
MAY_IMPORT = {
    "richmat_addon.core": (),
    "richmat_addon.blender": ("richmat_addon.core",),
    "richmat_addon": ("richmat_addon.core", "richmat_addon.blender"),
    "torch_models.assets": ("richmat_addon.core",),
    "torch_models.stage_clock": ("richmat_addon.core",),
    "torch_models": ("richmat_addon.core", "torch_models.assets", "torch_models.stage_clock"),
    "batch": ("richmat_addon", "torch_models"),
    "tools": ("richmat_addon", "torch_models"),  # the scripts that regenerate shipped tables
    "support": ("richmat_addon", "torch_models", "batch"),
    "bench": ("richmat_addon", "torch_models", "batch", "support"),
    "tests": ("richmat_addon", "torch_models", "batch", "tools", "support"),
}


def _modules() -> dict[str, Path]:
    found = {}
    for package in PACKAGES:
        for path in sorted((REPO / package).rglob("*.py")):
            parts = path.relative_to(REPO).with_suffix("").parts
            found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def _imported(name: str, path: Path, node: ast.Import | ast.ImportFrom, modules: dict[str, Path]) -> set[str]:
    """The repository modules an import statement loads (the innermost existing module of each name)."""
    if isinstance(node, ast.Import):
        names = [alias.name for alias in node.names]
    else:
        base = name.split(".")
        if node.level:  # relative to the module's package
            base = base[:len(base) - node.level + (path.name == "__init__.py")]
            base += node.module.split(".") if node.module else []
        else:
            base = node.module.split(".")
        prefix = ".".join(base)
        names = [f"{prefix}.{alias.name}" if f"{prefix}.{alias.name}" in modules else prefix for alias in node.names]
    out = set()
    for full in names:
        while full and full not in modules:
            full = full.rpartition(".")[0]
        if full and full != name:
            out.add(full)
    return out


def import_graph() -> dict[str, set[str]]:
    modules = _modules()
    graph = {}
    for name, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        graph[name] = set().union(*(_imported(name, path, n, modules) for n in ast.walk(tree)
                                    if isinstance(n, (ast.Import, ast.ImportFrom))))
    return graph


def _part(module: str) -> str:
    return max((p for p in MAY_IMPORT if module == p or module.startswith(p + ".")), key=len)


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), leaving out a package and its
    own module importing each other (a package's ``__init__`` naming a submodule is no design cycle)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while not component or component[-1] != v:
                component.append(stack.pop())
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return [c for c in found if not (len(c) == 2 and c[1].startswith(c[0] + "."))]


def arrows_up(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """The imports of a part that ``MAY_IMPORT`` does not allow it."""
    def allowed(a: str, b: str) -> bool:
        return _part(a) == _part(b) or any(_part(b) == p or _part(b).startswith(p + ".") for p in MAY_IMPORT[_part(a)])

    return sorted((a, b) for a, targets in graph.items() for b in targets if not allowed(a, b))


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph()


def test_no_import_cycles(graph: dict[str, set[str]]) -> None:
    assert cycles(graph) == []


def test_no_arrow_up_and_no_bench_tests_imports(graph: dict[str, set[str]]) -> None:
    assert arrows_up(graph) == []


def test_the_reader_sees_what_it_checks(graph: dict[str, set[str]]) -> None:
    """The checks above judge a graph the reader built right: known arrows are in it, and a planted
    cycle and a planted arrow up are found."""
    assert "richmat_addon.core.enhancement_types" in graph["richmat_addon.core.enhance"]  # from .x import
    assert "torch_models.generator.edm" in graph["torch_models.generator.dit"]  # from . import x
    assert "support.blender_child" in graph["tests.conftest"]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == [["a", "b", "c"]]
    assert cycles({"p": {"p.x"}, "p.x": {"p"}}) == []
    planted = {"richmat_addon.core.a": {"torch_models.b"}, "torch_models.b": {"richmat_addon.core.a"},
               "tests.c": {"bench.d"}, "bench.d": {"support.e"}, "support.e": set()}
    assert arrows_up(planted) == [("richmat_addon.core.a", "torch_models.b"), ("tests.c", "bench.d")]
    assert _part("richmat_addon.core.enhance") == "richmat_addon.core" and _part("bench.common") == "bench"
    shared = {"torch_models.assets.a": {"torch_models.render.b", "richmat_addon.core.c"},
              "torch_models.stage_clock": {"torch_models.assets.a"}, "torch_models.render.b": {"torch_models.assets.a"},
              "richmat_addon.core.c": set()}
    assert arrows_up(shared) == [("torch_models.assets.a", "torch_models.render.b"),
                                 ("torch_models.stage_clock", "torch_models.assets.a")]


# The hybrid decoder's room: the shipped decoder kind, which must not need the paper's MLP baseline's.
HYBRID_ROOM = "torch_models.neural.hybrid"
BASELINE_ROOM = "torch_models.neural.mlp"


def reached(graph: dict[str, set[str]], roots: tuple[str, ...]) -> set[str]:
    """Every module the ``roots`` load, directly or through others."""
    seen, todo = set(), list(roots)
    while todo:
        module = todo.pop()
        if module not in seen:
            seen.add(module)
            todo.extend(graph.get(module, ()))
    return seen


def test_the_hybrid_never_imports_the_mlp_baseline(graph: dict[str, set[str]]) -> None:
    """The baseline lives in its own room: nothing the hybrid's modules load, however indirectly, is in it,
    while the registry of kinds does reach it (so the reader follows the imports that matter)."""
    hybrid = tuple(m for m in graph if m.startswith(HYBRID_ROOM + "."))
    assert {HYBRID_ROOM + ".networks", HYBRID_ROOM + ".kind", HYBRID_ROOM + ".closure_form"} <= set(hybrid)
    assert [m for m in sorted(reached(graph, hybrid)) if m.startswith(BASELINE_ROOM)] == []
    assert BASELINE_ROOM + ".kind" in reached(graph, ("torch_models.neural.kinds",))
    assert reached({"a": {"b"}, "b": {"c"}, "c": set(), "d": {"a"}}, ("a",)) == {"a", "b", "c"}


# What the farm's Blender side (a stock Blender: no torch) imports from torch_models, and the preview scene the
# tests' and benches' Blender children build Cycles' ball from.
TORCH_FREE = (*sorted(f"torch_models.assets.{p.stem}" for p in (REPO / "torch_models" / "assets").glob("*.py")
                      if p.stem != "__init__"), "torch_models.stage_clock", "torch_models.render.preview_scene")


def test_the_modules_the_blender_side_imports_need_no_torch() -> None:
    """Each imports in a Python where ``import torch`` fails, as in a stock Blender; a module that needs torch
    does not (so the block is real)."""
    script = f"""
import importlib, sys
sys.modules["torch"] = None  # import torch now raises ImportError
for name in {TORCH_FREE!r}:
    importlib.import_module(name)
try:
    importlib.import_module("torch_models.render.ball")
except ImportError:
    print("blocked")
"""
    out = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["blocked"]
    assert "torch_models.assets.gltf_container" in TORCH_FREE  # the glob found the package
