"""Sheen (Zeltner LTC) in torch: ``lobes.sheen_*``; its colour multiplies the closure weight."""
from __future__ import annotations

from torch import Tensor

from richmat_addon.core import graph

from .. import lobes
from .kind import Material, TorchClosure, at_rows


def _eval(m: Material, lobe: graph.Lobe, wi: Tensor, wo: Tensor) -> Tensor:
    return lobes.sheen_eval(wi, wo, m.value(lobe.inputs["roughness"]))


def _albedo(m: Material, lobe: graph.Lobe, cos_i: Tensor) -> Tensor:
    return lobes.sheen_albedo(cos_i, m.value(lobe.inputs["roughness"]))


def _sample(m: Material, lobe: graph.Lobe, wi: Tensor, u: Tensor, rows: Tensor) -> Tensor:
    return lobes.sheen_sample(wi, at_rows(m.value(lobe.inputs["roughness"]), rows), u)


def _pdf(m: Material, lobe: graph.Lobe, wi: Tensor, wo: Tensor) -> Tensor:
    return lobes.sheen_pdf(wi, wo, m.value(lobe.inputs["roughness"]))


def _colour(m: Material, lobe: graph.Lobe) -> Tensor:
    """As ``w * c * sheen_bsdf(N, 1, r)`` in OSL."""
    return m.value(lobe.inputs["color"])


IMPLEMENTATION = TorchClosure(_eval, _albedo, _sample, _pdf, _colour)
