"""The enhanced material in Blender's own shader nodes: every Cycles device, EEVEE and exporters.

This walks the same pruned ``core.graph`` as the OSL writer. Each closure becomes
what its kind's native half makes (``native_closures/``): the BSDF node Cycles'
SVM has for the closure, scaled by the lobe weight, and, for a kind that can be a
layer's top, the lobe's layering albedo at the view cosine from the kind's fit.
``Layer(top, base)`` becomes ``top + clamp(1 - max_c(albedo(top)), 0, 1) * base``
with Add and Mix Shader nodes. A lobe reports ``max_c`` of its albedo,
``w A max_c(c)``; the terms of one top share their colour, so their sum is the max
of the summed colours. That is what Cycles' OSL ``layer()`` computes: one scalar
weight that depends only on the view direction (brdf-notes section 1). ``Mix`` and
``Add`` map to Mix and Add Shader. docs/backends.md says how close each closure is.
"""
from __future__ import annotations

import bpy

from ..core import graph, osl
from ..core.closures import KINDS
from .native_closures import NATIVE
from .native_nodes import Builder, FamilyClosure, Socket, Sockets, Value, group

NODE = "richmat_native"
EEVEE_NODE = "richmat_native_eevee"  # where EEVEE's graph differs (``eevee_differs``)


def _layer_fill(b: Builder, i: Sockets) -> Sockets:
    add = b.node("ShaderNodeAddShader")
    b.feed(add.inputs[0], i["Top"])
    b.feed(add.inputs[1], b.weighted(i["Base"], b.math("SUBTRACT", 1.0, i["Top Albedo"], clamp=True)))
    return {"Shader": add.outputs[0]}


def _layer() -> bpy.types.NodeTree:
    return group("richmat layer", [("Top", "shader"), ("Top Albedo", "float"), ("Base", "shader")],
                 [("Shader", "shader")], _layer_fill)


# ---- the material graph ---------------------------------------------------------------
def _colour(lobe: graph.Lobe) -> graph.Value:
    """The input that colours a lobe's layering albedo (white for a kind without one)."""
    key = KINDS[lobe.closure].colour_input
    return graph.WHITE if key is None else lobe.inputs.get(key, graph.WHITE)


class _Walker:
    """Turns graph nodes into (shader, albedo or None) sockets inside the material's group."""

    def __init__(self, b: Builder, inputs: Sockets, eevee: bool) -> None:
        self.b = b
        self.inputs = inputs
        self.eevee = eevee
        weight = b.node("ShaderNodeLayerWeight", "view cosine")
        b.feed(weight.inputs["Blend"], 0.5)
        b.feed(weight.inputs["Normal"], inputs["Normal"])
        self.cosine = b.math("SUBTRACT", 1.0, weight.outputs["Facing"])
        self._complements: dict[str, Socket] = {}

    def value(self, value: graph.Value) -> Value:
        if not isinstance(value, graph.Ref):
            return value
        if not value.one_minus:
            return self.inputs[value.name]
        if value.name not in self._complements:
            self._complements[value.name] = self.b.math("SUBTRACT", 1.0, self.inputs[value.name])
        return self._complements[value.name]

    def closure(self, node: graph.Lobe | graph.Diffuse) -> tuple[Socket, Socket | None]:
        return NATIVE[node.closure].build(self, node)

    def node(self, node: graph.Node) -> tuple[Socket, Socket | None]:
        b = self.b
        if isinstance(node, (graph.Lobe, graph.Diffuse)):
            return self.closure(node)
        if isinstance(node, graph.Add):
            shader, albedo = self.closure(node.terms[0])
            for term in node.terms[1:]:
                term_shader, term_albedo = self.closure(term)
                add = b.node("ShaderNodeAddShader")
                b.feed(add.inputs[0], shader)
                b.feed(add.inputs[1], term_shader)
                shader = add.outputs[0]
                albedo = b.math("ADD", albedo, term_albedo) if albedo and term_albedo else None
            return shader, albedo
        if isinstance(node, graph.Layer):
            terms = node.top.terms if isinstance(node.top, graph.Add) else (node.top,)
            if len({_colour(t) for t in terms}) > 1:
                raise ValueError(f"the terms of a layer's top must share a colour: {node.top!r}")
            top, albedo = self.node(node.top)
            if albedo is None:
                raise ValueError(f"a layer's top must report its albedo: {node.top!r}")
            base, _ = self.node(node.base)
            names = "+".join(lobe.name for lobe in graph.iter_lobes(node.top))
            layer = b.group(_layer(), f"layer {names}", Top=top, Top_Albedo=albedo, Base=base)
            return layer.outputs["Shader"], None
        if isinstance(node, graph.Mix):
            fg, _ = self.node(node.fg)
            bg, _ = self.node(node.bg)
            mix = b.node("ShaderNodeMixShader", node.mix.name)
            b.feed(mix.inputs[0], self.value(node.mix))
            b.feed(mix.inputs[1], bg)
            b.feed(mix.inputs[2], fg)
            return mix.outputs[0], None
        raise TypeError(f"not a graph node: {node!r}")


def eevee_differs(pruned: graph.Node) -> bool:
    """Whether EEVEE's graph of ``pruned`` draws some lobe in a form of its own (``Family.eevee``)."""
    return any(isinstance(native := NATIVE[lobe.closure], FamilyClosure) and native.family(lobe).eevee is not None
               for lobe in graph.iter_lobes(pruned))


def material_group(pruned: graph.Node, eevee: bool = False) -> bpy.types.NodeTree:
    """The group of a pruned graph, shared by the materials that keep the same lobes; with ``eevee``,
    the form EEVEE reads (``eevee_differs``).

    Its inputs are the OSL shader's (``osl.shader_inputs``), in the same order and
    with the same names, so the textures and constants feed both the same way.
    """
    inputs = osl.shader_inputs(pruned)

    def fill(b: Builder, sockets: Sockets) -> Sockets:
        return {"BSDF": _Walker(b, sockets, eevee).node(pruned)[0]}

    names = [lobe.name for lobe in graph.iter_lobes(pruned)]
    if any(i.name == "base_color" for i in inputs):  # the shader inputs have it when the graph has the diffuse
        names.append("diffuse")
    tree = group(f"richmat native{' eevee' if eevee else ''} ({' + '.join(names)})",
                 [(i.name, i.osl_type) for i in inputs], [("BSDF", "shader")], fill)
    items = {item.name: item for item in tree.interface.items_tree if item.in_out == "INPUT"}
    for inp in inputs:
        if not isinstance(inp.default, str):
            items[inp.name].default_value = (*inp.default, 1.0) if isinstance(inp.default, tuple) else inp.default
    return tree
