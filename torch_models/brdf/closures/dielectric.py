"""Dielectric GGX (reflection only, multi_ggx) in torch: ``lobes.dielectric_*``, GGX visible-normal sampling."""
from __future__ import annotations

from torch import Tensor

from richmat_addon.core import graph

from .. import lobes
from .kind import Material, TorchClosure, ggx_pdf, ggx_sample


def _eval(m: Material, lobe: graph.Lobe, wi: Tensor, wo: Tensor) -> Tensor:
    i = lobe.inputs
    return lobes.dielectric_eval(wi, wo, m.value(i["alpha"]), m.value(i["ior"]), m.value(i["tint"]))


def _albedo(m: Material, lobe: graph.Lobe, cos_i: Tensor) -> Tensor:
    i = lobe.inputs
    return lobes.dielectric_albedo(cos_i, m.value(i["alpha"]), m.value(i["ior"]), m.value(i["tint"]))


IMPLEMENTATION = TorchClosure(_eval, _albedo, ggx_sample, ggx_pdf)
