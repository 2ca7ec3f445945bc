"""Sheen in nodes: the Sheen BSDF (Microfiber), the same Zeltner closure as OSL's ``sheen_bsdf``.

Its layering albedo is ``w * max_c(c) * R`` with R from the core fit
(``core/closures/sheen.py``) in math nodes. EEVEE has no sheen of its own (it draws
the node as a diffuse), so its graph draws a diffuse of the sheen's reflectance.
"""
from __future__ import annotations

import bpy

from ...core.closures import sheen as kind
from ...core.schema import SHEEN_ROUGHNESS_MIN
from ..native_nodes import Builder, Family, FamilyClosure, Socket, Sockets, group, polynomial, strongest


def _albedo_fill(b: Builder, i: Sockets) -> Sockets:
    r = b.clamp(i["Roughness"], SHEEN_ROUGHNESS_MIN, 1.0)
    mu = i["Cosine"]
    width = b.math("MULTIPLY_ADD", b.math("MULTIPLY", r, r), kind.PEAK, kind.PEAK_FLOOR)
    features = b.node("ShaderNodeCombineXYZ", "exp(-mu / width), 1, 0")
    b.feed(features.inputs[0], b.math("EXPONENT", b.math("DIVIDE", b.math("MULTIPLY", mu, -1.0), width)))
    b.feed(features.inputs[1], 1.0)
    b.feed(features.inputs[2], 0.0)
    return {"Albedo": b.vector("DOT_PRODUCT", features.outputs[0], polynomial(b, kind.ALBEDO_FIT, mu, r))}


def albedo_group() -> bpy.types.NodeTree:
    """The fit of R(mu, roughness) as a node group."""
    return group("richmat sheen albedo", [("Cosine", "float"), ("Roughness", "float")], [("Albedo", "float")],
                 _albedo_fill)


def _albedo(b: Builder, i: Sockets, fit: bpy.types.Node) -> Socket:
    """The layering albedo ``w * max_c(c) * R``."""
    top = strongest(b, b.node("ShaderNodeSeparateXYZ"), i["Color"])
    return b.math("MULTIPLY", b.math("MULTIPLY", i["Weight"], top), fit.outputs["Albedo"])


def _fill(b: Builder, i: Sockets) -> Sockets:
    bsdf = b.bsdf("ShaderNodeBsdfSheen", i, distribution="MICROFIBER")
    b.feed(bsdf.inputs["Color"], i["Color"])
    b.feed(bsdf.inputs["Roughness"], i["Roughness"])
    fit = b.group(albedo_group(), Cosine=i["Cosine"], Roughness=i["Roughness"])
    return {"BSDF": b.weighted(bsdf.outputs[0], i["Weight"]), "Albedo": _albedo(b, i, fit)}


def _eevee_fill(b: Builder, i: Sockets) -> Sockets:
    """EEVEE draws a Sheen BSDF as a diffuse of its colour, several times the sheen's reflectance. A diffuse
    of colour ``c R(mu)`` reflects what the sheen reflects towards the viewer under uniform light."""
    fit = b.group(albedo_group(), Cosine=i["Cosine"], Roughness=i["Roughness"])
    diffuse = b.bsdf("ShaderNodeBsdfDiffuse", i)
    b.feed(diffuse.inputs["Color"], b.vector("SCALE", i["Color"], fit.outputs["Albedo"]))
    b.feed(diffuse.inputs["Roughness"], 0.0)
    return {"BSDF": b.weighted(diffuse.outputs[0], i["Weight"]), "Albedo": _albedo(b, i, fit)}


INPUTS = (("color", "color"), ("roughness", "float"))
IMPLEMENTATION = FamilyClosure((Family("sheen", INPUTS, _fill, eevee=Family("sheen eevee", INPUTS, _eevee_fill)),))
