"""Conductor GGX (multi_ggx) in torch: ``lobes.conductor_*`` with Gulbrandsen's (n, k), GGX sampling.

(n, k) depend on no direction, so each material computes them once per
(reflectivity, edge tint) pair.
"""
from __future__ import annotations

from torch import Tensor

from richmat_addon.core import graph

from .. import lobes
from .kind import Material, TorchClosure, ggx_pdf, ggx_sample


def _nk(m: Material, lobe: graph.Lobe) -> tuple[Tensor, Tensor]:
    r, g = lobe.inputs["reflectivity"], lobe.inputs["edge_tint"]

    def compute() -> tuple[Tensor, Tensor]:
        reflectivity = m.value(r)
        return lobes.gulbrandsen(reflectivity, m.value(g).expand_as(reflectivity))

    return m.cached(("gulbrandsen", r, g), compute)  # type: ignore[return-value]


def _eval(m: Material, lobe: graph.Lobe, wi: Tensor, wo: Tensor) -> Tensor:
    return lobes.conductor_eval(wi, wo, m.value(lobe.inputs["alpha"]), *_nk(m, lobe))


def _albedo(m: Material, lobe: graph.Lobe, cos_i: Tensor) -> Tensor:
    return lobes.conductor_albedo(cos_i, m.value(lobe.inputs["alpha"]), *_nk(m, lobe))


IMPLEMENTATION = TorchClosure(_eval, _albedo, ggx_sample, ggx_pdf)
