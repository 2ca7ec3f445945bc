"""Shared pieces of the native node graph: a node-adding builder, shared node groups, lobe families.

``native_builder`` walks the material graph with these, and each closure kind's
module in ``native_closures/`` builds its own groups with them. The node groups are
shared by every material of a file; their names carry ``VERSION``, so a .blend keeps
the groups it was built with and a newer add-on builds its own beside them.
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from typing import Callable, Optional, Protocol, Union

import bpy

from ..core import albedo_fits, graph
from ..core.schema import ALPHA_MIN

VERSION = 1

Socket = bpy.types.NodeSocket
Value = Union[Socket, float, tuple[float, ...]]
Sockets = dict[str, Socket]

_SOCKET_TYPES = {"float": "NodeSocketFloat", "color": "NodeSocketColor", "normal": "NodeSocketVector",
                 "vector": "NodeSocketVector", "shader": "NodeSocketShader"}
_COLUMN, _ROW = 240.0, 200.0  # layout pitch inside a group


def socket_name(key: str) -> str:
    """A graph input key as a group socket name: ``edge_tint`` -> ``Edge Tint``."""
    return "IOR" if key == "ior" else key.replace("_", " ").title()


class Builder:
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


def group(name: str, inputs: list[tuple[str, str]], outputs: list[tuple[str, str]],
          fill: Callable[[Builder, Sockets], Sockets]) -> bpy.types.NodeTree:
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
    b = Builder(tree)
    group_in = b.node("NodeGroupInput")
    group_out = b.node("NodeGroupOutput")
    results = fill(b, {s.name: s for s in group_in.outputs if s.name})
    for socket, value in results.items():
        b.feed(group_out.inputs[socket], value)
    _layout(tree)
    return tree


def polynomial(b: Builder, fit: albedo_fits.AlbedoFit, mu: Value, y: Value) -> Value:
    """``albedo_fits.polynomial`` as Vector Math multiply-adds (Horner in y, then in mu)."""
    total: Value | None = None
    for row in reversed(fit.coefficients):
        inner: Value = row[-1]
        for c in reversed(row[:-1]):
            inner = b.vector("MULTIPLY_ADD", inner, y, c)
        total = inner if total is None else b.vector("MULTIPLY_ADD", total, mu, inner)
    assert total is not None
    return total


def strongest(b: Builder, channels: bpy.types.Node, colour: Value) -> Socket:
    """max_c of ``colour``, split by the Separate XYZ node ``channels``."""
    b.feed(channels.inputs[0], colour)
    return b.math("MAXIMUM", b.math("MAXIMUM", channels.outputs[0], channels.outputs[1]), channels.outputs[2])


def roughness(b: Builder, alpha: Value) -> Socket:
    """The roughness r of a Blender BSDF node that squares it into GGX alpha = r^2."""
    return b.math("SQRT", b.clamp(alpha, ALPHA_MIN, 1.0))


@dataclass(frozen=True)
class Family:
    """A lobe family's node group: the graph inputs it takes (besides Cosine and Normal) and its inside.

    ``layered`` families report the lobe's layering albedo, max_c(weight x colour x fit),
    as a colour output, so the lobe can be a layer's top. ``eevee``, where set, is the
    family EEVEE's graph uses instead: a closer form where EEVEE draws the node Cycles
    uses in a way of its own (same inputs and outputs).
    """

    name: str
    inputs: tuple[tuple[str, str], ...]  # (graph input key, socket kind)
    fill: Callable[[Builder, Sockets], Sockets]
    layered: bool = True
    eevee: Optional[Family] = None

    def tree(self) -> bpy.types.NodeTree:
        inputs = [("Weight", "float"), *((socket_name(k), kind) for k, kind in self.inputs),
                  ("Cosine", "float"), ("Normal", "normal")]
        outputs = [("BSDF", "shader")] + ([("Albedo", "float")] if self.layered else [])
        return group(f"richmat {self.name}", inputs, outputs, self.fill)


class Walker(Protocol):
    """What a closure kind's native half may use of the material-graph walker."""

    b: Builder
    inputs: Sockets  # the material group's inputs, named as the OSL shader's
    cosine: Socket  # the view cosine
    eevee: bool  # building the graph EEVEE reads

    def value(self, value: graph.Value) -> Value: ...


class NativeClosure(Protocol):
    """A closure kind in Blender nodes: its shader and, if it can be a layer's top, its layering albedo."""

    def build(self, walker: Walker, node: graph.Lobe | graph.Diffuse) -> tuple[Socket, Optional[Socket]]: ...


@dataclass(frozen=True)
class FamilyClosure:
    """A closure kind drawn by one node group per lobe: ``choose`` picks the family (the first by default)."""

    families: tuple[Family, ...]
    choose: Optional[Callable[[graph.Lobe], Family]] = None

    def family(self, lobe: graph.Lobe) -> Family:
        return self.choose(lobe) if self.choose else self.families[0]

    def build(self, walker: Walker, lobe: graph.Lobe) -> tuple[Socket, Optional[Socket]]:
        family = self.family(lobe)
        family = family.eevee if walker.eevee and family.eevee else family
        node = walker.b.group(family.tree(), lobe.name, Weight=walker.value(lobe.weight), Cosine=walker.cosine,
                              Normal=walker.inputs["Normal"])
        for key, _ in family.inputs:
            walker.b.feed(node.inputs[socket_name(key)], walker.value(lobe.inputs[key]))
        return node.outputs["BSDF"], node.outputs.get("Albedo")
