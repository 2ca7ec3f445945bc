"""The enhanced material in Blender's own shader nodes: every Cycles device, EEVEE and exporters.

This walks the same pruned ``core.graph`` as the OSL writer. Each lobe becomes a
node of its family's group (``FAMILIES``): the BSDF node Cycles' SVM has for the
closure, scaled by the lobe weight with a Mix Shader, and the lobe's layering
albedo at the view cosine from the fits of ``core.albedo_fits``. ``Layer(top, base)``
becomes ``top + clamp(1 - max_c(albedo(top)), 0, 1) * base`` with Add and Mix
Shader nodes. A lobe reports ``max_c`` of its albedo, ``w A max_c(c)``; the terms of
one top share their colour, so their sum is the max of the summed colours. That is what Cycles' OSL ``layer()`` computes: one scalar weight
that depends only on the view direction (brdf-notes section 1). ``Mix`` and ``Add``
map to Mix and Add Shader.

Closures (docs/backends.md says how close each one is):

- sheen: Sheen BSDF (Microfiber), the same Zeltner closure as ``sheen_bsdf``;
- white dielectric: a Principled BSDF with a black base and Multiscatter GGX. Its
  specular lobe is ``dielectric_bsdf(..., "multi_ggx")``: the same Fresnel, the same
  energy compensation;
- tinted dielectric: no node tints a dielectric Fresnel, but a Metallic BSDF
  (Physical Conductor) of index (ior, 1, 1) and no extinction reflects the exact
  dielectric Fresnel in red and nothing in green and blue. Three of them, one per
  channel, scaled by the tint's channels, make ``tint x dielectric``;
- conductor: Metallic BSDF (Physical Conductor, Multiscatter GGX), with
  Gulbrandsen's (n, k) from ``artistic_ior`` computed in vector math;
- diffuse: Diffuse BSDF.

The node groups are shared by every material of a file. Their names carry
``VERSION``, so a .blend keeps the groups it was built with, and a newer
add-on builds its own groups beside them.
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from typing import Callable, Union

import bpy

from ..core import albedo_fits, graph, osl
from ..core.albedo_fit_data import DIELECTRIC, SHEEN
from ..core.schema import ALPHA_MIN, SHEEN_ROUGHNESS_MIN

VERSION = 1
NODE = "richmat_native"

Socket = bpy.types.NodeSocket
Value = Union[Socket, float, tuple[float, ...]]
Sockets = dict[str, Socket]

_SOCKET_TYPES = {"float": "NodeSocketFloat", "color": "NodeSocketColor", "normal": "NodeSocketVector",
                 "vector": "NodeSocketVector", "shader": "NodeSocketShader"}
# Graph input keys as socket names.
_SOCKET_NAMES = {"weight": "Weight", "roughness": "Roughness", "color": "Color", "ior": "IOR", "alpha": "Alpha",
                 "tint": "Tint", "reflectivity": "Reflectivity", "edge_tint": "Edge Tint"}
_COLUMN, _ROW = 240.0, 200.0  # layout pitch inside a group


class _Builder:
    """Adds nodes to one tree and feeds their inputs with sockets (linked) or constants (set)."""

    def __init__(self, tree: bpy.types.NodeTree) -> None:
        self.tree = tree

    def node(self, kind: str, label: str = "", **settings: object) -> bpy.types.Node:
        node = self.tree.nodes.new(kind)
        node.label = label
        for key, value in settings.items():
            setattr(node, key, value)
        return node

    def feed(self, socket: Socket, value: Value) -> None:
        if isinstance(value, bpy.types.NodeSocket):
            self.tree.links.new(value, socket)
        elif socket.type == "RGBA":
            socket.default_value = (*value, 1.0)[:4] if isinstance(value, tuple) else (value, value, value, 1.0)
        else:
            socket.default_value = value

    def group(self, group: bpy.types.NodeTree, label: str = "", **inputs: Value) -> bpy.types.Node:
        node = self.node("ShaderNodeGroup", label or group.name)
        node.node_tree = group
        for name, value in inputs.items():
            self.feed(node.inputs[name.replace("_", " ")], value)
        return node

    def math(self, operation: str, *values: Value, clamp: bool = False) -> Socket:
        node = self.node("ShaderNodeMath", operation=operation, use_clamp=clamp)
        for socket, value in zip(node.inputs, values):
            self.feed(socket, value)
        return node.outputs[0]

    def clamp(self, value: Value, lo: float, hi: float) -> Socket:
        return self.math("MINIMUM", self.math("MAXIMUM", value, lo), hi)

    def vector(self, operation: str, *values: Value) -> Socket:
        """Vector Math; SCALE takes (vector, scale), DOT_PRODUCT returns its Value output."""
        node = self.node("ShaderNodeVectorMath", operation=operation)
        sockets = [node.inputs[0], node.inputs["Scale"]] if operation == "SCALE" else node.inputs
        for socket, value in zip(sockets, values):
            self.feed(socket, value)
        return node.outputs["Value" if operation == "DOT_PRODUCT" else "Vector"]

    def weighted(self, shader: Socket, weight: Value) -> Socket:
        """``weight * shader``: a Mix Shader whose first shader is nothing."""
        mix = self.node("ShaderNodeMixShader")
        self.feed(mix.inputs[0], weight)
        self.feed(mix.inputs[2], shader)
        return mix.outputs[0]

    def bsdf(self, kind: str, inputs: Sockets, **settings: object) -> bpy.types.Node:
        """A BSDF node on the group's Normal."""
        node = self.node(kind, **settings)
        self.feed(node.inputs["Normal"], inputs["Normal"])
        return node


def _layout(tree: bpy.types.NodeTree) -> None:
    """Columns by longest path from the inputs, so a group reads left to right."""
    columns: dict[str, int] = {}

    def column(node: bpy.types.Node) -> int:
        if node.name not in columns:
            upstream = [link.from_node for socket in node.inputs for link in socket.links]
            columns[node.name] = 1 + max((column(n) for n in upstream), default=-1)
        return columns[node.name]

    rows: dict[int, int] = defaultdict(int)
    for node in tree.nodes:
        c = column(node)
        node.location = (c * _COLUMN, -rows[c] * _ROW)
        rows[c] += 1


def _group(name: str, inputs: list[tuple[str, str]], outputs: list[tuple[str, str]],
           fill: Callable[[_Builder, Sockets], Sockets]) -> bpy.types.NodeTree:
    """The shared group ``name`` (with ``VERSION``), built by ``fill`` when the file lacks it."""
    full = f"{name} v{VERSION}"
    tree = bpy.data.node_groups.get(full)
    if tree is not None:
        return tree
    tree = bpy.data.node_groups.new(full, "ShaderNodeTree")
    for socket, kind in inputs:
        tree.interface.new_socket(socket, in_out="INPUT", socket_type=_SOCKET_TYPES[kind])
    for socket, kind in outputs:
        tree.interface.new_socket(socket, in_out="OUTPUT", socket_type=_SOCKET_TYPES[kind])
    b = _Builder(tree)
    group_in = b.node("NodeGroupInput")
    group_out = b.node("NodeGroupOutput")
    results = fill(b, {s.name: s for s in group_in.outputs if s.name})
    for socket, value in results.items():
        b.feed(group_out.inputs[socket], value)
    _layout(tree)
    return tree


# ---- albedo fits ---------------------------------------------------------------------
def _polynomial(b: _Builder, fit: albedo_fits.AlbedoFit, mu: Value, y: Value) -> Value:
    """``albedo_fits.polynomial`` as Vector Math multiply-adds (Horner in y, then in mu)."""
    total: Value | None = None
    for row in reversed(fit.coefficients):
        inner: Value = row[-1]
        for c in reversed(row[:-1]):
            inner = b.vector("MULTIPLY_ADD", inner, y, c)
        total = inner if total is None else b.vector("MULTIPLY_ADD", total, mu, inner)
    assert total is not None
    return total


def _dielectric_albedo_fill(b: _Builder, i: Sockets) -> Sockets:
    alpha = b.clamp(i["Alpha"], ALPHA_MIN, 1.0)
    mu = i["Cosine"]
    widened = b.math("SQRT", b.math("MULTIPLY_ADD", mu, mu, b.math(
        "MULTIPLY", albedo_fits.MU_WIDEN, b.math("POWER", alpha, albedo_fits.MU_WIDEN_POWER))))
    grazing = b.math("POWER", b.math("MAXIMUM", b.math("SUBTRACT", 1.0, widened), 0.0), albedo_fits.GRAZING_POWER)
    f0 = b.math("POWER", b.math("DIVIDE", b.math("SUBTRACT", i["IOR"], 1.0), b.math("ADD", i["IOR"], 1.0)), 2.0)
    features = b.node("ShaderNodeCombineXYZ", "grazing, F0, 1")
    b.feed(features.inputs[0], grazing)
    b.feed(features.inputs[1], f0)
    b.feed(features.inputs[2], 1.0)
    y = b.math("SQRT", alpha)
    return {"Albedo": b.vector("DOT_PRODUCT", features.outputs[0], _polynomial(b, DIELECTRIC, mu, y))}


def _sheen_albedo_fill(b: _Builder, i: Sockets) -> Sockets:
    r = b.clamp(i["Roughness"], SHEEN_ROUGHNESS_MIN, 1.0)
    mu = i["Cosine"]
    width = b.math("MULTIPLY_ADD", b.math("MULTIPLY", r, r), albedo_fits.SHEEN_PEAK, albedo_fits.SHEEN_PEAK_FLOOR)
    features = b.node("ShaderNodeCombineXYZ", "exp(-mu / width), 1, 0")
    b.feed(features.inputs[0], b.math("EXPONENT", b.math("DIVIDE", b.math("MULTIPLY", mu, -1.0), width)))
    b.feed(features.inputs[1], 1.0)
    b.feed(features.inputs[2], 0.0)
    return {"Albedo": b.vector("DOT_PRODUCT", features.outputs[0], _polynomial(b, SHEEN, mu, r))}


def _dielectric_albedo() -> bpy.types.NodeTree:
    return _group("richmat dielectric albedo", [("Cosine", "float"), ("Alpha", "float"), ("IOR", "float")],
                  [("Albedo", "float")], _dielectric_albedo_fill)


def _sheen_albedo() -> bpy.types.NodeTree:
    return _group("richmat sheen albedo", [("Cosine", "float"), ("Roughness", "float")], [("Albedo", "float")],
                  _sheen_albedo_fill)


def _artistic_ior_fill(b: _Builder, i: Sockets) -> Sockets:
    """OSL's ``artistic_ior`` (Gulbrandsen 2014) per channel."""
    one = (1.0, 1.0, 1.0)
    r = b.vector("MINIMUM", b.vector("MAXIMUM", i["Reflectivity"], (0.0, 0.0, 0.0)), (0.99, 0.99, 0.99))
    root = b.vector("POWER", r, (0.5, 0.5, 0.5))
    n_min = b.vector("DIVIDE", b.vector("SUBTRACT", one, r), b.vector("ADD", one, r))
    n_max = b.vector("DIVIDE", b.vector("ADD", one, root), b.vector("SUBTRACT", one, root))
    n = b.vector("MULTIPLY_ADD", b.vector("SUBTRACT", n_min, n_max), i["Edge Tint"], n_max)
    above, below = b.vector("ADD", n, one), b.vector("SUBTRACT", n, one)
    k2 = b.vector("DIVIDE", b.vector("SUBTRACT", b.vector("MULTIPLY", r, b.vector("MULTIPLY", above, above)),
                                      b.vector("MULTIPLY", below, below)), b.vector("SUBTRACT", one, r))
    return {"IOR": n, "Extinction": b.vector("POWER", b.vector("MAXIMUM", k2, (0.0, 0.0, 0.0)), (0.5, 0.5, 0.5))}


def _strongest(b: _Builder, channels: bpy.types.Node, colour: Value) -> Socket:
    """max_c of ``colour``, split by the Separate XYZ node ``channels``."""
    b.feed(channels.inputs[0], colour)
    return b.math("MAXIMUM", b.math("MAXIMUM", channels.outputs[0], channels.outputs[1]), channels.outputs[2])


def _roughness(b: _Builder, alpha: Value) -> Socket:
    """The roughness r of a Blender BSDF node that squares it into GGX alpha = r^2."""
    return b.math("SQRT", b.clamp(alpha, ALPHA_MIN, 1.0))


# ---- lobe families -------------------------------------------------------------------
def _sheen_fill(b: _Builder, i: Sockets) -> Sockets:
    bsdf = b.bsdf("ShaderNodeBsdfSheen", i, distribution="MICROFIBER")
    b.feed(bsdf.inputs["Color"], i["Color"])
    b.feed(bsdf.inputs["Roughness"], i["Roughness"])
    fit = b.group(_sheen_albedo(), Cosine=i["Cosine"], Roughness=i["Roughness"])
    strongest = _strongest(b, b.node("ShaderNodeSeparateXYZ"), i["Color"])
    return {"BSDF": b.weighted(bsdf.outputs[0], i["Weight"]),
            "Albedo": b.math("MULTIPLY", b.math("MULTIPLY", i["Weight"], strongest), fit.outputs["Albedo"])}


def _specular(b: _Builder, i: Sockets) -> Socket:
    """``dielectric_bsdf(..., "multi_ggx")`` with a white tint: the specular lobe of a black Principled BSDF."""
    bsdf = b.bsdf("ShaderNodeBsdfPrincipled", i, distribution="MULTI_GGX", label="specular only (black base)")
    b.feed(bsdf.inputs["Base Color"], (0.0, 0.0, 0.0))
    b.feed(bsdf.inputs["Roughness"], _roughness(b, i["Alpha"]))
    b.feed(bsdf.inputs["IOR"], i["IOR"])
    return bsdf.outputs[0]


def _dielectric_fill(b: _Builder, i: Sockets) -> Sockets:
    fit = b.group(_dielectric_albedo(), Cosine=i["Cosine"], Alpha=i["Alpha"], IOR=i["IOR"])
    return {"BSDF": b.weighted(_specular(b, i), i["Weight"]),
            "Albedo": b.math("MULTIPLY", i["Weight"], fit.outputs["Albedo"])}


def _tinted_dielectric_fill(b: _Builder, i: Sockets) -> Sockets:
    """``tint x dielectric``, one channel at a time: a conductor of index (ior, 1, 1) reflects the dielectric's
    exact Fresnel in red and nothing elsewhere (k = 0, n = 1 is no interface), scaled by the tint's red."""
    fit = b.group(_dielectric_albedo(), Cosine=i["Cosine"], Alpha=i["Alpha"], IOR=i["IOR"])
    tint = b.node("ShaderNodeSeparateXYZ")
    strongest = _strongest(b, tint, i["Tint"])
    roughness = _roughness(b, i["Alpha"])
    total: Socket | None = None
    for channel in range(3):
        ior = b.node("ShaderNodeCombineXYZ", f"IOR in channel {channel} only")
        for k in range(3):
            b.feed(ior.inputs[k], i["IOR"] if k == channel else 1.0)
        bsdf = b.bsdf("ShaderNodeBsdfMetallic", i, fresnel_type="PHYSICAL_CONDUCTOR", distribution="MULTI_GGX")
        b.feed(bsdf.inputs["IOR"], ior.outputs[0])
        b.feed(bsdf.inputs["Extinction"], (0.0, 0.0, 0.0))
        b.feed(bsdf.inputs["Roughness"], roughness)
        lobe = b.weighted(bsdf.outputs[0], tint.outputs[channel])
        if total is None:
            total = lobe
        else:
            add = b.node("ShaderNodeAddShader")
            b.feed(add.inputs[0], total)
            b.feed(add.inputs[1], lobe)
            total = add.outputs[0]
    assert total is not None
    return {"BSDF": b.weighted(total, i["Weight"]),
            "Albedo": b.math("MULTIPLY", b.math("MULTIPLY", i["Weight"], strongest), fit.outputs["Albedo"])}


def _conductor_fill(b: _Builder, i: Sockets) -> Sockets:
    ior = b.group(_group("richmat artistic ior", [("Reflectivity", "color"), ("Edge Tint", "float")],
                         [("IOR", "vector"), ("Extinction", "vector")], _artistic_ior_fill),
                  Reflectivity=i["Reflectivity"], Edge_Tint=i["Edge Tint"])
    bsdf = b.bsdf("ShaderNodeBsdfMetallic", i, fresnel_type="PHYSICAL_CONDUCTOR", distribution="MULTI_GGX")
    b.feed(bsdf.inputs["IOR"], ior.outputs["IOR"])
    b.feed(bsdf.inputs["Extinction"], ior.outputs["Extinction"])
    b.feed(bsdf.inputs["Roughness"], _roughness(b, i["Alpha"]))
    return {"BSDF": b.weighted(bsdf.outputs[0], i["Weight"])}


@dataclass(frozen=True)
class Family:
    """A lobe family's node group: the graph inputs it takes (besides Cosine and Normal) and its inside.

    ``layered`` families report the lobe's layering albedo, max_c(weight x colour x fit),
    as a colour output, so the lobe can be a layer's top.
    """

    name: str
    inputs: tuple[tuple[str, str], ...]  # (graph input key, socket kind)
    fill: Callable[[_Builder, Sockets], Sockets]
    layered: bool = True

    def tree(self) -> bpy.types.NodeTree:
        inputs = [("Weight", "float"), *((_SOCKET_NAMES[k], kind) for k, kind in self.inputs),
                  ("Cosine", "float"), ("Normal", "normal")]
        outputs = [("BSDF", "shader")] + ([("Albedo", "float")] if self.layered else [])
        return _group(f"richmat {self.name}", inputs, outputs, self.fill)


FAMILIES: dict[str, Family] = {f.name: f for f in (
    Family("sheen", (("color", "color"), ("roughness", "float")), _sheen_fill),
    Family("dielectric", (("ior", "float"), ("alpha", "float")), _dielectric_fill),
    Family("tinted dielectric", (("tint", "color"), ("ior", "float"), ("alpha", "float")), _tinted_dielectric_fill),
    Family("conductor", (("reflectivity", "color"), ("edge_tint", "float"), ("alpha", "float")), _conductor_fill,
           layered=False),
)}


def family_of(lobe: graph.Lobe) -> Family:
    """The family that renders ``lobe``: a dielectric with a tint other than white needs one lobe per channel."""
    if lobe.closure == "dielectric" and lobe.inputs.get("tint", graph.WHITE) != graph.WHITE:
        return FAMILIES["tinted dielectric"]
    return FAMILIES[lobe.closure]


def _layer_fill(b: _Builder, i: Sockets) -> Sockets:
    add = b.node("ShaderNodeAddShader")
    b.feed(add.inputs[0], i["Top"])
    b.feed(add.inputs[1], b.weighted(i["Base"], b.math("SUBTRACT", 1.0, i["Top Albedo"], clamp=True)))
    return {"Shader": add.outputs[0]}


def _layer() -> bpy.types.NodeTree:
    return _group("richmat layer", [("Top", "shader"), ("Top Albedo", "float"), ("Base", "shader")],
                  [("Shader", "shader")], _layer_fill)


# ---- the material graph ---------------------------------------------------------------
class _Walker:
    """Turns graph nodes into (shader, albedo or None) sockets inside the material's group."""

    def __init__(self, b: _Builder, inputs: Sockets) -> None:
        self.b = b
        self.inputs = inputs
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

    def lobe(self, lobe: graph.Lobe) -> tuple[Socket, Socket | None]:
        family = family_of(lobe)
        node = self.b.group(family.tree(), lobe.name, Weight=self.value(lobe.weight), Cosine=self.cosine,
                            Normal=self.inputs["Normal"])
        for key, _ in family.inputs:
            self.b.feed(node.inputs[_SOCKET_NAMES[key]], self.value(lobe.inputs[key]))
        return node.outputs["BSDF"], node.outputs.get("Albedo")

    def node(self, node: graph.Node) -> tuple[Socket, Socket | None]:
        b = self.b
        if isinstance(node, graph.Lobe):
            return self.lobe(node)
        if isinstance(node, graph.Add):
            shader, albedo = self.lobe(node.terms[0])
            for term in node.terms[1:]:
                term_shader, term_albedo = self.lobe(term)
                add = b.node("ShaderNodeAddShader")
                b.feed(add.inputs[0], shader)
                b.feed(add.inputs[1], term_shader)
                shader = add.outputs[0]
                albedo = b.math("ADD", albedo, term_albedo) if albedo and term_albedo else None
            return shader, albedo
        if isinstance(node, graph.Layer):
            terms = node.top.terms if isinstance(node.top, graph.Add) else (node.top,)
            if len({t.inputs.get("color", t.inputs.get("tint", graph.WHITE)) for t in terms}) > 1:
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
        if isinstance(node, graph.Diffuse):
            diffuse = b.bsdf("ShaderNodeBsdfDiffuse", self.inputs, label=node.name)
            b.feed(diffuse.inputs["Color"], self.inputs["base_color"])
            return diffuse.outputs[0], None
        raise TypeError(f"not a graph node: {node!r}")


def material_group(pruned: graph.Node) -> bpy.types.NodeTree:
    """The group of a pruned graph, shared by the materials that keep the same lobes.

    Its inputs are the OSL shader's (``osl.shader_inputs``), in the same order and
    with the same names, so the textures and constants feed both the same way.
    """
    inputs = osl.shader_inputs(pruned)

    def fill(b: _Builder, sockets: Sockets) -> Sockets:
        return {"BSDF": _Walker(b, sockets).node(pruned)[0]}

    names = [lobe.name for lobe in graph.iter_lobes(pruned)]
    if any(i.name == "base_color" for i in inputs):  # the shader inputs have it when the graph has the diffuse
        names.append("diffuse")
    tree = _group(f"richmat native ({' + '.join(names)})", [(i.name, i.osl_type) for i in inputs],
                  [("BSDF", "shader")], fill)
    items = {item.name: item for item in tree.interface.items_tree if item.in_out == "INPUT"}
    for inp in inputs:
        if not isinstance(inp.default, str):
            items[inp.name].default_value = (*inp.default, 1.0) if isinstance(inp.default, tuple) else inp.default
    return tree
