"""Conductor GGX in nodes: a Metallic BSDF (Physical Conductor, Multiscatter GGX).

Gulbrandsen's (n, k) come from OSL's ``artistic_ior`` arithmetic in Vector Math.
A conductor is never a layer's top, so it reports no albedo.
"""
from __future__ import annotations

from ..native_nodes import Builder, Family, FamilyClosure, Sockets, group, roughness


def _artistic_ior_fill(b: Builder, i: Sockets) -> Sockets:
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


def _fill(b: Builder, i: Sockets) -> Sockets:
    ior = b.group(group("richmat artistic ior", [("Reflectivity", "color"), ("Edge Tint", "float")],
                        [("IOR", "vector"), ("Extinction", "vector")], _artistic_ior_fill),
                  Reflectivity=i["Reflectivity"], Edge_Tint=i["Edge Tint"])
    bsdf = b.bsdf("ShaderNodeBsdfMetallic", i, fresnel_type="PHYSICAL_CONDUCTOR", distribution="MULTI_GGX")
    b.feed(bsdf.inputs["IOR"], ior.outputs["IOR"])
    b.feed(bsdf.inputs["Extinction"], ior.outputs["Extinction"])
    b.feed(bsdf.inputs["Roughness"], roughness(b, i["Alpha"]))
    return {"BSDF": b.weighted(bsdf.outputs[0], i["Weight"])}


IMPLEMENTATION = FamilyClosure((Family("conductor", (("reflectivity", "color"), ("edge_tint", "float"),
                                                     ("alpha", "float")), _fill, layered=False),))
