"""Export the enhanced material as a MaterialX 1.39 document (pbrlib nodes).

The document is made by walking the same graph as the OSL backend, pruned by the
material's constants. Each closure is the node its kind's ``mtlx`` emitter makes
(``core/closures/``; docs/backends.md lists them); Layer/Mix/Add become
``layer`` / ``mix`` / ``add``.

Lobe weights go into each BSDF's ``weight`` input: MaterialX's ``multiply`` would
scale the response but leave the throughput seen by the base unchanged.
MaterialX's throughput ignores tints and colours, so a coloured top is authored
as ``weight' = w * max(c)``, ``colour' = c / max(c)``: the response is unchanged
and the base is attenuated by ``1 - w max(c) A``, as in Cycles and torch.
Roughness inputs are vector2 GGX alphas (alpha, alpha). Nothing 1.39.5-only
(``retroreflective``) is authored, so 1.39.0+ readers (Blender 5.0 bundles
1.39.3) load the files.
"""
from __future__ import annotations

import functools
import os
from pathlib import Path
from typing import Any, Callable, Union

import MaterialX as mx

from . import graph, schema
from .closures import KINDS
from .maps import EnhancedMaterial, ParamMap

COLOR_SPACE = "lin_rec709"  # our maps hold linear Rec.709 values
# Guard for c / max(c) when a texel of a coloured top is black (its weight is 0 then).
_MAX_EPS = 1e-6

Color = tuple[float, float, float]
# A value in the document being built: a constant, a node, or (node, output) of a multioutput node.
Operand = Union[float, Color, mx.Node, tuple[mx.Node, str]]


@functools.lru_cache(maxsize=1)
def standard_libraries() -> mx.Document:
    """The standard data libraries (stdlib, pbrlib, ...) bundled with the MaterialX package."""
    lib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
    return lib


def _label(v: graph.Value) -> str:
    """Name stem of the nodes derived from a graph value."""
    if isinstance(v, graph.Ref):
        return f"one_minus_{v.name}" if v.one_minus else v.name
    return "constant"


def _is_const(x: Operand) -> bool:
    return isinstance(x, float) or (isinstance(x, tuple) and not isinstance(x[0], mx.Node))


class _Builder:
    """Creates the nodes of one document; folds arithmetic on constants into values."""

    def __init__(self, doc: mx.Document, mat: EnhancedMaterial, texture_paths: dict[str, str]):
        self.doc = doc
        self.mat = mat
        self.paths = texture_paths
        self._memo: dict[tuple[Any, ...], Operand] = {}

    def memo(self, key: tuple[Any, ...], make: Callable[[], Operand]) -> Operand:
        """Build a derived value once: a texture, an alpha pair, a max channel ... is shared."""
        if key not in self._memo:
            self._memo[key] = make()
        return self._memo[key]

    # -- nodes and inputs ---------------------------------------------------------------
    def node(self, category: str, name: str, out_type: str, **inputs: tuple[str, Operand]) -> mx.Node:
        node = self.doc.addNode(category, self.doc.createValidChildName(name), out_type)
        for input_name, (input_type, value) in inputs.items():
            self.connect(node, input_name, input_type, value)
        return node

    def connect(self, node: mx.Node, name: str, input_type: str, value: Operand) -> None:
        if isinstance(value, mx.Node):
            node.addInput(name, input_type).setConnectedNode(value)
        elif isinstance(value, tuple) and isinstance(value[0], mx.Node):
            inp = node.addInput(name, input_type)
            inp.setConnectedNode(value[0])
            inp.setOutputString(value[1])
        elif input_type == "color3":
            node.setInputValue(name, mx.Color3(*value), input_type)
        elif input_type == "vector2":
            node.setInputValue(name, mx.Vector2(*value), input_type)
        else:
            node.setInputValue(name, value, input_type)

    # -- parameters ---------------------------------------------------------------------
    def _map(self, name: str) -> ParamMap:
        return self.mat.base_color if name == "base_color" else self.mat.params[name]

    def param(self, name: str) -> Operand:
        """A constant for constant maps, else one shared ``image`` node per parameter."""
        return self.memo(("param", name), lambda: self._param(name))

    def _param(self, name: str) -> Operand:
        pmap = self._map(name)
        is_color = name == "base_color" or schema.PARAM_BY_NAME[name].kind == "color"
        if pmap.is_constant:
            v = tuple(float(x) for x in pmap.value)
            return v if is_color else v[0]
        if name not in self.paths:
            raise KeyError(f"no texture path for textured parameter {name!r}")
        tex = self.node("image", f"tex_{name}", "color3" if is_color else "float")
        file = tex.addInput("file", "filename")
        file.setValueString(Path(self.paths[name]).as_posix())
        if is_color:
            file.setColorSpace(COLOR_SPACE)
        return tex

    def value(self, v: graph.Value) -> Operand:
        if isinstance(v, graph.Ref):
            x = self.param(v.name)
            return self.memo(("value", v), lambda: self.one_minus(x, _label(v))) if v.one_minus else x
        return tuple(float(c) for c in v) if isinstance(v, tuple) else float(v)

    # -- arithmetic with constant folding; ``name`` names the node made otherwise ------------
    def one_minus(self, x: Operand, name: str) -> Operand:
        if _is_const(x):
            return 1.0 - x  # type: ignore[operator]
        return self.node("subtract", name, "float", in1=("float", 1.0), in2=("float", x))

    def mul(self, a: Operand, b: Operand, name: str) -> Operand:
        if _is_const(a) and _is_const(b):
            return a * b  # type: ignore[operator]
        if _is_const(a) and a == 1.0:
            return b
        return self.node("multiply", name, "float", in1=("float", a), in2=("float", b))

    def max_channel(self, c: Operand, name: str) -> Operand:
        if _is_const(c):
            return max(c)  # type: ignore[arg-type]
        r, g, b = (self.node("extract", f"{name}_{ch}", "float", **{"in": ("color3", c)},
                             index=("integer", i)) for i, ch in enumerate("rgb"))
        rg = self.node("max", f"{name}_max_rg", "float", in1=("float", r), in2=("float", g))
        return self.node("max", f"{name}_max", "float", in1=("float", rg), in2=("float", b))

    def normalized(self, c: Operand, m: Operand, name: str) -> Operand:
        """c / max(m, eps): the colour of a top with its largest channel moved into the weight."""
        if _is_const(c) and _is_const(m):
            return tuple(x / max(m, _MAX_EPS) for x in c)  # type: ignore[union-attr,arg-type]
        guard = max(m, _MAX_EPS) if _is_const(m) else self.node(
            "max", f"{name}_max_guarded", "float", in1=("float", m), in2=("float", _MAX_EPS))
        return self.node("divide", f"{name}_normalized", "color3", in1=("color3", c), in2=("float", guard))

    def clamped(self, v: graph.Value, lo: float) -> Operand:
        """``v`` clamped to [lo, 1] like the OSL shader does."""
        x = self.value(v)
        if _is_const(x):
            return min(max(x, lo), 1.0)  # type: ignore[type-var]
        return self.memo(("clamp", v, lo), lambda: self.node(
            "clamp", f"{_label(v)}_clamped", "float", **{"in": ("float", x)},
            low=("float", lo), high=("float", 1.0)))

    def alpha2(self, v: graph.Value) -> Operand:
        """vector2 (alpha, alpha) of a clamped GGX alpha."""
        a = self.clamped(v, schema.ALPHA_MIN)
        if _is_const(a):
            return (a, a)  # type: ignore[return-value]
        return self.memo(("alpha2", v), lambda: self.node(
            "combine2", f"{_label(v)}_pair", "vector2", in1=("float", a), in2=("float", a)))

    def as_color(self, v: graph.Value) -> Operand:
        x = self.value(v)
        if _is_const(x):
            return x if isinstance(x, tuple) else (x, x, x)  # type: ignore[return-value]
        if isinstance(x, mx.Node) and x.getType() == "color3":
            return x
        return self.memo(("color", v), lambda: self.node(
            "convert", f"{_label(v)}_color", "color3", **{"in": ("float", x)}))

    def coloured_weight(self, lobe: graph.Lobe, color_input: str) -> tuple[Operand, Operand]:
        """(weight', colour') with the normalisation trick; identity for a white top."""
        w = self.value(lobe.weight)
        source = lobe.inputs[color_input]
        c = self.value(source)
        if _is_const(c) and c == graph.WHITE:
            return w, c
        name = _label(source)
        m = self.memo(("max", source), lambda: self.max_channel(c, name))
        return (self.mul(w, m, f"{lobe.name}_weight"),
                self.memo(("normalized", source), lambda: self.normalized(c, m, name)))

    # -- graph ----------------------------------------------------------------------------
    def build(self, node: graph.Node) -> mx.Node:
        if isinstance(node, (graph.Lobe, graph.Diffuse)):
            return KINDS[node.closure].mtlx(self, node)
        if isinstance(node, graph.Add):
            terms = [KINDS[t.closure].mtlx(self, t) for t in node.terms]
            total = terms[0]
            for term in terms[1:]:
                total = self.node("add", f"{total.getName()}_plus_{term.getName()}", "BSDF",
                                  in1=("BSDF", total), in2=("BSDF", term))
            return total
        if isinstance(node, graph.Layer):
            top = self.build(node.top)
            base = self.build(node.base)
            return self.node("layer", f"{top.getName()}_layer", "BSDF",
                             top=("BSDF", top), base=("BSDF", base))
        if isinstance(node, graph.Mix):
            fg = self.build(node.fg)
            bg = self.build(node.bg)
            return self.node("mix", f"mix_{node.mix.name}", "BSDF", fg=("BSDF", fg), bg=("BSDF", bg),
                             mix=("float", self.value(node.mix)))
        raise TypeError(f"not a graph node: {node!r}")


def to_materialx(mat: EnhancedMaterial, texture_paths: dict[str, str],
                 surface: graph.Node = graph.SURFACE) -> mx.Document:
    """The document of ``mat``: its pruned graph, a ``surface`` and a ``surfacematerial``.

    ``texture_paths`` (parameter name or ``"base_color"`` -> file) is authored as given.
    """
    pruned = graph.prune(surface, mat.constants())
    if pruned is None:
        raise ValueError("the material graph pruned to nothing")
    doc = mx.createDocument()
    doc.setColorSpace(COLOR_SPACE)
    builder = _Builder(doc, mat, texture_paths)
    bsdf = builder.build(pruned)
    surface = builder.node("surface", "richmat_surface", "surfaceshader", bsdf=("BSDF", bsdf))
    builder.node("surfacematerial", mx.createValidName(mat.name), "material",
                 surfaceshader=("surfaceshader", surface))
    return doc


def write_materialx(mat: EnhancedMaterial, texture_paths: dict[str, str], path: str | os.PathLike) -> Path:
    """Write ``mat`` to ``path`` with texture paths relative to the document's folder."""
    path = Path(path)
    folder = path.parent.resolve()
    relative = {k: os.path.relpath(Path(p).resolve(), folder) for k, p in texture_paths.items()}
    path.parent.mkdir(parents=True, exist_ok=True)
    mx.writeToXmlFile(to_materialx(mat, relative), str(path))
    return path


def _enum_values(nodedef_input: mx.Input) -> list[str]:
    return [e.strip() for e in nodedef_input.getAttribute("enum").split(",") if e.strip()]


def validate_document(doc: mx.Document) -> list[str]:
    """Problems found in ``doc`` against the standard libraries; empty when valid.

    Besides ``Document.validate`` (which ignores enum values), checks that every node
    resolves a nodedef and that string inputs with an ``enum`` hold a listed value.
    """
    checked = mx.createDocument()
    checked.copyContentFrom(doc)
    checked.setDataLibrary(standard_libraries())
    problems: list[str] = []
    ok, message = checked.validate()
    if not ok:
        problems += [ln for ln in message.splitlines() if ln.strip()]
    nodes = list(checked.getNodes())
    for ng in checked.getNodeGraphs():
        nodes += ng.getNodes()
    for node in nodes:
        nodedef = node.getNodeDef()
        if nodedef is None:
            problems.append(f"{node.getNamePath()}: no nodedef for {node.getCategory()} ({node.getType()})")
            continue
        for inp in node.getInputs():
            decl = nodedef.getActiveInput(inp.getName())
            if decl is None or inp.getType() != "string" or not inp.getValueString():
                continue
            allowed = _enum_values(decl)
            if allowed and inp.getValueString() not in allowed:
                problems.append(f"{inp.getNamePath()}: {inp.getValueString()!r} is not one of {allowed}")
    return problems


def _describe(inp: mx.Input) -> Any:
    """An input as data: its value, or the upstream node with its own inputs (recursively)."""
    upstream = inp.getConnectedNode()
    if upstream is None:
        value = inp.getValue()
        return list(value) if isinstance(value, (mx.Color3, mx.Vector2, mx.Vector3)) else value
    out: dict[str, Any] = {"node": upstream.getCategory(), "name": upstream.getName(),
                           "inputs": {i.getName(): _describe(i) for i in upstream.getInputs()}}
    if inp.getOutputString():
        out["output"] = inp.getOutputString()
    return out


_COMBINERS = {"layer": ("top", "base"), "mix": ("fg", "bg"), "add": ("in1", "in2")}


def read_back(path: str | os.PathLike) -> dict[str, Any]:
    """Read a written document back as data, for comparison with its source.

    Returns ``structure`` (nested lists ``[category, child, child]`` with lobe names
    at the leaves), ``lobes`` (per BSDF node: category and inputs, upstream nodes
    described recursively) and ``textures`` (parameter name -> file as written).
    """
    doc = mx.createDocument()
    mx.readFromXmlFile(doc, str(path))
    lobes: dict[str, Any] = {}

    def walk(node: mx.Node) -> Any:
        category = node.getCategory()
        if category in _COMBINERS:
            return [category, *(walk(node.getConnectedNode(i)) for i in _COMBINERS[category])]
        lobes[node.getName()] = {"node": category,
                                 "inputs": {i.getName(): _describe(i) for i in node.getInputs()}}
        return node.getName()

    material = doc.getMaterialNodes()[0]
    surface = material.getConnectedNode("surfaceshader")
    textures = {n.getName()[len("tex_"):]: n.getInputValue("file")
                for n in doc.getNodes() if n.getCategory() == "image"}
    return {"material": material.getName(), "structure": walk(surface.getConnectedNode("bsdf")),
            "lobes": lobes, "textures": textures}
