"""Closed-form fits of the layering albedos Cycles reads from its tables.

Cycles' OSL ``layer(top, base)`` scales the base by ``1 - max_c(albedo(top))``,
the albedo read at the view cosine from lookup tables no shader node can reach
(brdf-notes section 1). The native node graph (``blender/native_builder.py``)
emulates that weight in math nodes, so it needs the albedos as formulas:

each closure kind that can be a layer's top keeps its fit in its module
(``core/closures/dielectric.py``, ``sheen.py``). Each fit is
``dot(features, P(mu, y))``: three features carry the shape (the kind's module
defines them) and ``P`` is a small polynomial with 3-vector coefficients, which a node graph evaluates with a few Vector Math multiply-adds.
Every shading point evaluates them, so they are kept to a few math nodes each. The
coefficients are fitted to the torch tables (which match Cycles') by
``tools/albedo_fits.py`` into ``albedo_fit_data.py``.

Pure Python: the add-on evaluates nothing here; the tests and the tool do.
"""
from __future__ import annotations

from dataclasses import dataclass

Vector = tuple[float, float, float]


@dataclass(frozen=True)
class AlbedoFit:
    """``dot(features, P(mu, y))`` with ``P = sum_ij coefficients[i][j] mu^i y^j``.

    ``y`` is the kind's roughness coordinate (sqrt(alpha) for the dielectric).
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


def dot(a: Vector, b: Vector) -> float:
    return sum(x * y for x, y in zip(a, b))
