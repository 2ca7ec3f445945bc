"""Dielectric GGX, reflection only: ``dielectric_bsdf(N, T, tint, 0, a, a, ior, "multi_ggx")``.

Inputs: ``ior``, ``alpha`` (GGX alpha, clamped to [1e-4, 1]) and ``tint``, the
reflection tint. ``"multi_ggx"`` makes Cycles' layer albedo the energy-preserved
lobe's true albedo. MaterialX: ``dielectric_bsdf`` with scatter mode ``"R"`` and
the tint normalised into the weight. The layering-albedo fit A(mu, alpha, ior)
per unit weight and white tint serves the native node graph.
"""
from __future__ import annotations

import math
from typing import Any

from .. import albedo_fits, graph
from ..albedo_fit_data import DIELECTRIC as ALBEDO_FIT
from ..schema import ALPHA_MIN
from .kind import GGX_DISTRIBUTION, ClosureKind, MtlxBuilder, OslWriter

# The fit's grazing feature is max(1 - mu_eff, 0)^GRAZING_POWER at
# mu_eff = sqrt(mu^2 + MU_WIDEN * alpha^MU_WIDEN_POWER): roughness smears the grazing rise.
MU_WIDEN, MU_WIDEN_POWER, GRAZING_POWER = 1.0, 1.0, 5.0


def _osl(w: OslWriter, lobe: graph.Lobe) -> str:
    a = w.clamped(lobe.inputs["alpha"], ALPHA_MIN)
    return (f"{w.value(lobe.weight)} * dielectric_bsdf(Nn, U, {w.as_color(lobe.inputs['tint'])}, color(0), "
            f"{a}, {a}, {w.value(lobe.inputs['ior'])}, \"{GGX_DISTRIBUTION}\")")


def _mtlx(b: MtlxBuilder, lobe: graph.Lobe) -> Any:
    weight, tint = b.coloured_weight(lobe, "tint")
    node = b.node("dielectric_bsdf", lobe.name, "BSDF", weight=("float", weight), tint=("color3", tint),
                  ior=("float", b.value(lobe.inputs["ior"])), roughness=("vector2", b.alpha2(lobe.inputs["alpha"])))
    node.setInputValue("scatter_mode", "R", "string")
    return node


def features(mu: float, alpha: float, ior: float) -> albedo_fits.Vector:
    widened = math.sqrt(mu * mu + MU_WIDEN * alpha ** MU_WIDEN_POWER)
    return max(1.0 - widened, 0.0) ** GRAZING_POWER, albedo_fits.f0(ior), 1.0


def fitted_albedo(mu: float, alpha: float, ior: float, fit: albedo_fits.AlbedoFit = ALBEDO_FIT) -> float:
    """The fit at (mu, alpha, ior), alpha clamped as the lobe clamps it; its y is sqrt(alpha)."""
    alpha = min(max(alpha, ALPHA_MIN), 1.0)
    return albedo_fits.dot(features(mu, alpha, ior), albedo_fits.polynomial(fit, mu, math.sqrt(alpha)))


IMPLEMENTATION = ClosureKind(inputs=("ior", "alpha", "tint"), osl=_osl, mtlx=_mtlx, colour_input="tint")
