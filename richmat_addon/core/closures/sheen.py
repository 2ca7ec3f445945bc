"""Sheen: Zeltner et al. 2022 LTC, the one sheen Cycles has (``sheen_bsdf``).

Inputs: ``roughness`` (used directly, clamped to [1e-3, 1] as Cycles does) and
``color``, a multiplier of the closure: ``w * c * sheen_bsdf(N, color(1), r)``,
because ``sheen_bsdf`` counts its albedo argument twice in Cycles' layer albedo.
MaterialX: ``sheen_bsdf`` with mode ``"zeltner"`` and the colour normalised into
the weight (docs/backends.md). The layering-albedo fit R(mu, r) serves the
native node graph, which cannot read Cycles' table.
"""
from __future__ import annotations

import math
from typing import Any

from .. import albedo_fits, graph
from ..albedo_fit_data import SHEEN as ALBEDO_FIT
from ..schema import SHEEN_ROUGHNESS_MIN
from .kind import ClosureKind, MtlxBuilder, OslWriter

MODE = "zeltner"
# The fit's feature exp(-mu / (PEAK * r^2 + PEAK_FLOOR)): low roughness only shows at grazing.
PEAK, PEAK_FLOOR = 2.0, 1e-3


def _osl(w: OslWriter, lobe: graph.Lobe) -> str:
    color = lobe.inputs["color"]
    scale = "" if color == graph.WHITE else f" * {w.as_color(color)}"
    rough = w.clamped(lobe.inputs["roughness"], SHEEN_ROUGHNESS_MIN)
    return f"{w.value(lobe.weight)}{scale} * sheen_bsdf(Nn, color(1), {rough})"


def _mtlx(b: MtlxBuilder, lobe: graph.Lobe) -> Any:
    weight, color = b.coloured_weight(lobe, "color")
    rough = b.clamped(lobe.inputs["roughness"], SHEEN_ROUGHNESS_MIN)
    node = b.node("sheen_bsdf", lobe.name, "BSDF", weight=("float", weight), color=("color3", color),
                  roughness=("float", rough))
    node.setInputValue("mode", MODE, "string")
    return node


def features(mu: float, roughness: float) -> albedo_fits.Vector:
    return math.exp(-mu / (PEAK * roughness * roughness + PEAK_FLOOR)), 1.0, 0.0


def fitted_albedo(mu: float, roughness: float, fit: albedo_fits.AlbedoFit = ALBEDO_FIT) -> float:
    """The fit of R at (mu, roughness), roughness clamped as the closure clamps it."""
    roughness = min(max(roughness, SHEEN_ROUGHNESS_MIN), 1.0)
    return albedo_fits.dot(features(mu, roughness), albedo_fits.polynomial(fit, mu, roughness))


IMPLEMENTATION = ClosureKind(inputs=("roughness", "color"), osl=_osl, mtlx=_mtlx, colour_input="color")
