"""Closed-form fits of the layering albedos Cycles reads from its tables.

Cycles' OSL ``layer(top, base)`` scales the base by ``1 - max_c(albedo(top))``,
the albedo read at the view cosine from lookup tables no shader node can reach
(brdf-notes section 1). The native node graph (``blender/native_builder.py``)
emulates that weight in math nodes, so it needs the albedos as formulas:

- ``DIELECTRIC``: a reflection-only ``dielectric_bsdf`` with ``"multi_ggx"``,
  per unit weight and white tint, of (mu, alpha, ior);
- ``SHEEN``: Zeltner's sheen albedo R of (mu, roughness).

Each fit is ``dot(features, P(mu, y))``: three features carry the shape (a
Schlick-like grazing rise at a roughness-widened cosine and F0; an exponential
for the sheen's grazing peak) and ``P`` is a small polynomial with 3-vector
coefficients, which a node graph evaluates with a few Vector Math multiply-adds.
Every shading point evaluates them, so they are kept to a few math nodes each. The
coefficients are fitted to the torch tables (which match Cycles') by
``tools/albedo_fits.py`` into ``albedo_fit_data.py``.

Pure Python: the add-on evaluates nothing here; the tests and the tool do.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .schema import ALPHA_MIN, SHEEN_ROUGHNESS_MIN

Vector = tuple[float, float, float]

# The dielectric's grazing feature is max(1 - mu_eff, 0)^GRAZING_POWER at
# mu_eff = sqrt(mu^2 + MU_WIDEN * alpha^MU_WIDEN_POWER): roughness smears the grazing rise.
MU_WIDEN, MU_WIDEN_POWER, GRAZING_POWER = 1.0, 1.0, 5.0
# The sheen's feature exp(-mu / (SHEEN_PEAK * r^2 + SHEEN_PEAK_FLOOR)): low roughness only shows at grazing.
SHEEN_PEAK, SHEEN_PEAK_FLOOR = 2.0, 1e-3


@dataclass(frozen=True)
class AlbedoFit:
    """``dot(features, P(mu, y))`` with ``P = sum_ij coefficients[i][j] mu^i y^j``.

    ``y`` is sqrt(alpha) for ``DIELECTRIC`` and the roughness for ``SHEEN``.
    ``max_error`` and ``rms_error`` are against the torch tables over mu in
    [0.1, 1] (the rim below that is looser) on the fit's domain.
    """

    name: str
    coefficients: tuple[tuple[Vector, ...], ...]
    max_error: float
    rms_error: float


def polynomial(fit: AlbedoFit, mu: float, y: float) -> Vector:
    """``P(mu, y)`` by Horner's rule, in the order the node graph evaluates it."""
    total = (0.0, 0.0, 0.0)
    for row in reversed(fit.coefficients):
        inner = (0.0, 0.0, 0.0)
        for c in reversed(row):
            inner = tuple(a * y + b for a, b in zip(inner, c))
        total = tuple(a * mu + b for a, b in zip(total, inner))
    return total  # type: ignore[return-value]


def f0(ior: float) -> float:
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def dielectric_features(mu: float, alpha: float, ior: float) -> Vector:
    widened = math.sqrt(mu * mu + MU_WIDEN * alpha ** MU_WIDEN_POWER)
    return max(1.0 - widened, 0.0) ** GRAZING_POWER, f0(ior), 1.0


def sheen_features(mu: float, roughness: float) -> Vector:
    return math.exp(-mu / (SHEEN_PEAK * roughness * roughness + SHEEN_PEAK_FLOOR)), 1.0, 0.0


def _dot(a: Vector, b: Vector) -> float:
    return sum(x * y for x, y in zip(a, b))


def dielectric(fit: AlbedoFit, mu: float, alpha: float, ior: float) -> float:
    """A dielectric fit at (mu, alpha, ior), alpha clamped as the lobes clamp it."""
    alpha = min(max(alpha, ALPHA_MIN), 1.0)
    return _dot(dielectric_features(mu, alpha, ior), polynomial(fit, mu, math.sqrt(alpha)))


def sheen(fit: AlbedoFit, mu: float, roughness: float) -> float:
    roughness = min(max(roughness, SHEEN_ROUGHNESS_MIN), 1.0)
    return _dot(sheen_features(mu, roughness), polynomial(fit, mu, roughness))
