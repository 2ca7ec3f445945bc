"""Dielectric GGX (reflection only) in nodes.

- white tint: a Principled BSDF with a black base and Multiscatter GGX; its
  specular lobe is ``dielectric_bsdf(..., "multi_ggx")``, the same Fresnel and the
  same energy compensation;
- other tints: no node tints a dielectric Fresnel, but a Metallic BSDF (Physical
  Conductor) of index (ior, 1, 1) and no extinction reflects the exact dielectric
  Fresnel in red and nothing in green and blue. Three of them, one per channel,
  scaled by the tint's channels, make ``tint x dielectric``.

The layering albedo is the core fit (``core/closures/dielectric.py``) in math nodes.
"""
from __future__ import annotations

from typing import Optional

import bpy

from ...core import graph
from ...core.closures import dielectric as kind
from ...core.schema import ALPHA_MIN
from ..native_nodes import Builder, Family, FamilyClosure, Socket, Sockets, group, polynomial, roughness, strongest


def _albedo_fill(b: Builder, i: Sockets) -> Sockets:
    alpha = b.clamp(i["Alpha"], ALPHA_MIN, 1.0)
    mu = i["Cosine"]
    widened = b.math("SQRT", b.math("MULTIPLY_ADD", mu, mu, b.math(
        "MULTIPLY", kind.MU_WIDEN, b.math("POWER", alpha, kind.MU_WIDEN_POWER))))
    grazing = b.math("POWER", b.math("MAXIMUM", b.math("SUBTRACT", 1.0, widened), 0.0), kind.GRAZING_POWER)
    f0 = b.math("POWER", b.math("DIVIDE", b.math("SUBTRACT", i["IOR"], 1.0), b.math("ADD", i["IOR"], 1.0)), 2.0)
    features = b.node("ShaderNodeCombineXYZ", "grazing, F0, 1")
    b.feed(features.inputs[0], grazing)
    b.feed(features.inputs[1], f0)
    b.feed(features.inputs[2], 1.0)
    y = b.math("SQRT", alpha)
    return {"Albedo": b.vector("DOT_PRODUCT", features.outputs[0], polynomial(b, kind.ALBEDO_FIT, mu, y))}


def albedo_group() -> bpy.types.NodeTree:
    """The fit of A(mu, alpha, ior) per unit weight and white tint as a node group."""
    return group("richmat dielectric albedo", [("Cosine", "float"), ("Alpha", "float"), ("IOR", "float")],
                 [("Albedo", "float")], _albedo_fill)


def _specular(b: Builder, i: Sockets) -> Socket:
    """``dielectric_bsdf(..., "multi_ggx")`` with a white tint: the specular lobe of a black Principled BSDF."""
    bsdf = b.bsdf("ShaderNodeBsdfPrincipled", i, distribution="MULTI_GGX", label="specular only (black base)")
    b.feed(bsdf.inputs["Base Color"], (0.0, 0.0, 0.0))
    b.feed(bsdf.inputs["Roughness"], roughness(b, i["Alpha"]))
    b.feed(bsdf.inputs["IOR"], i["IOR"])
    return bsdf.outputs[0]


def _white_fill(b: Builder, i: Sockets) -> Sockets:
    fit = b.group(albedo_group(), Cosine=i["Cosine"], Alpha=i["Alpha"], IOR=i["IOR"])
    return {"BSDF": b.weighted(_specular(b, i), i["Weight"]),
            "Albedo": b.math("MULTIPLY", i["Weight"], fit.outputs["Albedo"])}


def _tinted_fill(b: Builder, i: Sockets) -> Sockets:
    """``tint x dielectric``, one channel at a time: a conductor of index (ior, 1, 1) reflects the dielectric's
    exact Fresnel in red and nothing elsewhere (k = 0, n = 1 is no interface), scaled by the tint's red."""
    fit = b.group(albedo_group(), Cosine=i["Cosine"], Alpha=i["Alpha"], IOR=i["IOR"])
    tint = b.node("ShaderNodeSeparateXYZ")
    top = strongest(b, tint, i["Tint"])
    rough = roughness(b, i["Alpha"])
    total: Optional[Socket] = None
    for channel in range(3):
        ior = b.node("ShaderNodeCombineXYZ", f"IOR in channel {channel} only")
        for k in range(3):
            b.feed(ior.inputs[k], i["IOR"] if k == channel else 1.0)
        bsdf = b.bsdf("ShaderNodeBsdfMetallic", i, fresnel_type="PHYSICAL_CONDUCTOR", distribution="MULTI_GGX")
        b.feed(bsdf.inputs["IOR"], ior.outputs[0])
        b.feed(bsdf.inputs["Extinction"], (0.0, 0.0, 0.0))
        b.feed(bsdf.inputs["Roughness"], rough)
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
            "Albedo": b.math("MULTIPLY", b.math("MULTIPLY", i["Weight"], top), fit.outputs["Albedo"])}


WHITE = Family("dielectric", (("ior", "float"), ("alpha", "float")), _white_fill)
TINTED = Family("tinted dielectric", (("tint", "color"), ("ior", "float"), ("alpha", "float")), _tinted_fill)


def _choose(lobe: graph.Lobe) -> Family:
    """A tint other than white needs one lobe per channel."""
    return TINTED if lobe.inputs.get("tint", graph.WHITE) != graph.WHITE else WHITE


IMPLEMENTATION = FamilyClosure((WHITE, TINTED), _choose)
