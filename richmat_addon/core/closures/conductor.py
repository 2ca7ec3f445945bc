"""Conductor GGX: ``conductor_bsdf(N, T, a, a, n, k, "multi_ggx")`` with Gulbrandsen's (n, k).

Inputs: ``reflectivity`` (r, a colour) and ``edge_tint`` (g), turned into the
complex index by ``artistic_ior`` (OSL and MaterialX share its arithmetic), and
``alpha``. A conductor reports albedo 1 as a layer top in Cycles, so the graph
only ever mixes it; it has no layering-albedo fit.
"""
from __future__ import annotations

from typing import Any

from .. import graph
from ..schema import ALPHA_MIN
from .kind import GGX_DISTRIBUTION, ClosureKind, MtlxBuilder, OslWriter


def _osl(w: OslWriter, lobe: graph.Lobe) -> str:
    n, k = _osl_artistic_ior(w, lobe)
    a = w.clamped(lobe.inputs["alpha"], ALPHA_MIN)
    return f"{w.value(lobe.weight)} * conductor_bsdf(Nn, U, {a}, {a}, {n}, {k}, \"{GGX_DISTRIBUTION}\")"


def _osl_artistic_ior(w: OslWriter, lobe: graph.Lobe) -> tuple[str, str]:
    """(n, k) declared once per distinct (reflectivity, edge tint) pair."""
    r, g = w.as_color(lobe.inputs["reflectivity"]), w.as_color(lobe.inputs["edge_tint"])

    def declare() -> str:
        var = w.local(lobe.name)
        w.declare(f"color {var}_n, {var}_k;")
        w.declare(f"artistic_ior({r}, {g}, {var}_n, {var}_k);")
        return var

    var = w.once(("artistic_ior", r, g), declare)
    return f"{var}_n", f"{var}_k"


def _mtlx(b: MtlxBuilder, lobe: graph.Lobe) -> Any:
    reflectivity, edge_tint = lobe.inputs["reflectivity"], lobe.inputs["edge_tint"]
    ior = b.memo(("artistic_ior", reflectivity, edge_tint), lambda: b.node(
        "artistic_ior", "artistic_ior", "multioutput", reflectivity=("color3", b.as_color(reflectivity)),
        edge_color=("color3", b.as_color(edge_tint))))
    return b.node("conductor_bsdf", lobe.name, "BSDF", weight=("float", b.value(lobe.weight)),
                  ior=("color3", (ior, "ior")), extinction=("color3", (ior, "extinction")),
                  roughness=("vector2", b.alpha2(lobe.inputs["alpha"])))


IMPLEMENTATION = ClosureKind(inputs=("reflectivity", "edge_tint", "alpha"), osl=_osl, mtlx=_mtlx)
