"""Generate the Cycles OSL shader of the enhanced material from ``graph``.

The shader text is produced by walking a (possibly pruned) graph, so the lobe
stack exists only in ``graph.py``. Conventions (docs/backends.md, brdf-notes §8):

* right-nested ``layer(top, base)``: Cycles loses the outer attenuation when a
  layer sits inside a top, and the graph is built that way;
* lobe weights and colours are closure *multipliers*: Cycles then reports a layer
  albedo of ``w * c * A`` and attenuates the base by ``1 - max_c(w c A)``;
* each closure is written by its kind's emitter (``core/closures/``), which also
  says why it takes the form it does (``"multi_ggx"``, the white sheen albedo).

Pure Python: runs inside a stock Blender and in the torch process alike.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Union

from . import graph, schema
from .closures import KINDS

Default = Union[float, tuple[float, float, float], str]

# The shader's base colour default: Blender's usual mid grey.
BASE_COLOR_DEFAULT: tuple[float, float, float] = (0.8, 0.8, 0.8)


@dataclass(frozen=True)
class ShaderInput:
    """One shader parameter; the Cycles builder makes one Script-node socket per input.

    ``default`` is a float, an RGB triple, or an OSL expression (``"N"``) for
    globals, which Blender shows as an unconnected socket without a value.
    """

    name: str
    osl_type: str
    default: Default

    def declaration(self) -> str:
        return f"{self.osl_type} {self.name} = {_literal(self.default)}"


def _literal(value: Default) -> str:
    if isinstance(value, str):
        return value
    if isinstance(value, tuple):
        return "color({:g}, {:g}, {:g})".format(*value)
    return f"{float(value):g}"


def _referenced(node: graph.Node) -> set[str]:
    """Parameter names a graph reads (a pruned graph reads fewer)."""
    names: set[str] = set()
    for lobe in graph.iter_lobes(node):
        names.add(lobe.weight.name)
        names.update(v.name for v in lobe.inputs.values() if isinstance(v, graph.Ref))
    stack = [node]
    while stack:
        n = stack.pop()
        if isinstance(n, graph.Mix):
            names.add(n.mix.name)
            stack += [n.fg, n.bg]
        elif isinstance(n, graph.Layer):
            stack.append(n.base)
    return names


def _has_diffuse(node: graph.Node) -> bool:
    if isinstance(node, graph.Diffuse):
        return True
    if isinstance(node, graph.Layer):
        return _has_diffuse(node.base)
    if isinstance(node, graph.Mix):
        return _has_diffuse(node.fg) or _has_diffuse(node.bg)
    return False


def shader_inputs(node: graph.Node = graph.SURFACE) -> list[ShaderInput]:
    """The shader's inputs in declaration order: base colour, used parameters (schema order), Normal."""
    used = _referenced(node)
    inputs = [ShaderInput("base_color", "color", BASE_COLOR_DEFAULT)] if _has_diffuse(node) else []
    inputs += [ShaderInput(p.name, p.kind, p.default) for p in schema.PARAMS if p.name in used]
    inputs.append(ShaderInput("Normal", "normal", "N"))
    return inputs


def _value(value: graph.Value) -> str:
    if isinstance(value, graph.Ref):
        return f"(1.0 - {value.name})" if value.one_minus else value.name
    return _literal(value)


def _as_color(value: graph.Value) -> str:
    """OSL expression of a value used as a colour (float parameters are promoted)."""
    if isinstance(value, graph.Ref) and schema.PARAM_BY_NAME[value.name].kind == "float":
        return f"color({_value(value)})"
    if isinstance(value, (int, float)):
        return f"color({float(value):g})"
    return _value(value)


def _local(name: str) -> str:
    """Local variable of a lobe; prefixed because lobe names such as ``diffuse`` are OSL builtins."""
    return f"lobe_{name}"


class _Writer:
    """Accumulates local statements, then composes the closure expression.

    Each closure kind's ``osl`` emitter (``core/closures/``) writes its lobe through
    the methods below; the writer only walks the combinators.
    """

    def __init__(self) -> None:
        self.lines: list[str] = []
        self._shared: dict[tuple[object, ...], str] = {}
        self._clamped: dict[str, str] = {}

    value = staticmethod(_value)
    as_color = staticmethod(_as_color)
    local = staticmethod(_local)

    def declare(self, line: str) -> None:
        self.lines.append(line)

    def once(self, key: tuple[object, ...], make: Callable[[], str]) -> str:
        """``make()`` (which declares locals and returns a name) the first time ``key`` is asked for."""
        if key not in self._shared:
            self._shared[key] = make()
        return self._shared[key]

    def clamped(self, value: graph.Value, lo: float) -> str:
        """A float local holding ``value`` clamped to [lo, 1], declared once per value."""
        expr = f"clamp({_value(value)}, {lo:g}, 1.0)"
        if expr not in self._clamped:
            if isinstance(value, graph.Ref):
                base = f"one_minus_{value.name}" if value.one_minus else value.name
            else:
                base = f"const{len(self._clamped)}"
            var = self._clamped[expr] = f"{base}_clamped"
            self.lines.append(f"float {var} = {expr};")
        return self._clamped[expr]

    def closure(self, node: graph.Lobe | graph.Diffuse) -> str:
        expr = KINDS[node.closure].osl(self, node)
        var = _local(node.name)
        self.lines.append(f"closure color {var} = {expr};")
        return var

    def node(self, node: graph.Node) -> str:
        if isinstance(node, (graph.Lobe, graph.Diffuse)):
            return self.closure(node)
        if isinstance(node, graph.Add):
            return "(" + " + ".join(self.closure(t) for t in node.terms) + ")"
        if isinstance(node, graph.Layer):
            top = self.node(node.top)
            return f"layer({top}, {self.node(node.base)})"
        if isinstance(node, graph.Mix):
            fg = self.node(node.fg)
            return f"mix({self.node(node.bg)}, {fg}, {_value(node.mix)})"
        raise TypeError(f"not a graph node: {node!r}")


def osl_source(node: graph.Node = graph.SURFACE, name: str = "richmat_enhanced") -> str:
    """OSL source of ``node`` as a Cycles Script-node shader with output ``BSDF``."""
    writer = _Writer()
    result = writer.node(node)
    params = ",\n".join(f"    {i.declaration()}" for i in shader_inputs(node))
    body = "\n".join(f"    {ln}" for ln in writer.lines)
    return (
        "// Generated by richmat_addon.core.osl from the material graph; do not edit.\n"
        f"shader {name}(\n{params},\n    output closure color BSDF = 0)\n"
        "{\n"
        "    normal Nn = normalize(Normal);\n"
        "    vector U = normalize(dPdu);  // isotropic lobes: any tangent will do\n"
        f"{body}\n"
        f"    BSDF = {result};\n"
        "}\n"
    )
