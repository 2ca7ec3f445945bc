"""A toy closure kind, ``toy_lambert`` (a weighted, coloured Lambertian lobe), for the registry test.

Each floor's half is built here as a developer would write the kind's module on that floor;
``registered`` enters them into the tables for the duration of a ``with`` block, so nothing else
is edited. The Blender half imports bpy only when asked for, because the pytest process does not.
"""
from __future__ import annotations

import math
from contextlib import ExitStack, contextmanager
from typing import Any, Iterator

from richmat_addon.core import graph
from richmat_addon.core.closures import KINDS, ClosureKind

NAME = "toy_lambert"
# A toy lobe as a layer's top over the diffuse base; it reads two parameters of the schema.
GRAPH = graph.Layer(graph.Lobe("toy", NAME, graph.Ref("dust_weight"), {"color": graph.Ref("scatter_color")}),
                    graph.Diffuse())


def _osl(w: Any, lobe: graph.Lobe) -> str:
    return f"{w.value(lobe.weight)} * {w.as_color(lobe.inputs['color'])} * diffuse(Nn)"


def _mtlx(b: Any, lobe: graph.Lobe) -> Any:
    weight, color = b.coloured_weight(lobe, "color")
    return b.node("oren_nayar_diffuse_bsdf", lobe.name, "BSDF", weight=("float", weight),
                  color=("color3", color), roughness=("float", 0.0))


CORE = ClosureKind(inputs=("color",), osl=_osl, mtlx=_mtlx, colour_input="color")


def torch_half() -> Any:
    import torch

    from torch_models.brdf.closures.kind import TorchClosure

    def cosine_sample(m: Any, node: Any, wi: Any, u: Any, rows: Any) -> Any:
        r, phi = u[..., 0].sqrt(), 2.0 * math.pi * u[..., 1]
        return torch.stack([r * phi.cos(), r * phi.sin(), (1.0 - u[..., 0]).clamp(min=0.0).sqrt()], -1)

    return TorchClosure(
        eval=lambda m, node, wi, wo: wo[..., 2:3].clamp(min=0.0) * (wi[..., 2:3] > 0) / math.pi,
        albedo=lambda m, node, cos_i: torch.ones_like(cos_i),
        sample=cosine_sample,
        pdf=lambda m, node, wi, wo: wo[..., 2:3].clamp(min=0.0) / math.pi,
        colour=lambda m, node: m.value(node.inputs["color"]))


def native_half() -> Any:
    from richmat_addon.blender.native_nodes import Builder, Family, FamilyClosure, Sockets, strongest

    def fill(b: Builder, i: Sockets) -> Sockets:
        bsdf = b.bsdf("ShaderNodeBsdfDiffuse", i)
        b.feed(bsdf.inputs["Color"], i["Color"])
        top = strongest(b, b.node("ShaderNodeSeparateXYZ"), i["Color"])
        return {"BSDF": b.weighted(bsdf.outputs[0], i["Weight"]), "Albedo": b.math("MULTIPLY", i["Weight"], top)}

    return FamilyClosure((Family("toy lambert", (("color", "color"),), fill),))


@contextmanager
def registered(torch_floor: bool = False, native_floor: bool = False) -> Iterator[None]:
    """The toy kind in the core table, and in the torch and Blender tables when asked for."""
    with ExitStack() as stack:
        stack.enter_context(KINDS.registered(NAME, CORE))
        if torch_floor:
            from torch_models.brdf.closures import TORCH
            stack.enter_context(TORCH.registered(NAME, torch_half()))
        if native_floor:
            from richmat_addon.blender.native_closures import NATIVE
            stack.enter_context(NATIVE.registered(NAME, native_half()))
        yield
