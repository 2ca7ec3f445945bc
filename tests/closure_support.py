"""What the closure tests share: directions, quadrature, and a closure kind on a one-lobe material.

``one_lobe`` puts a single lobe of any registered kind into a ``LayeredBsdf``, so a
kind's test reaches its torch half through the registry, as the layered model does.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np
import torch
from torch import Tensor

from richmat_addon.core import graph
from tests.chi2 import Chi2Result, chi2_test
from torch_models.brdf import lobes
from torch_models.brdf.closures import TORCH
from torch_models.brdf.model import LayeredBsdf

F64 = torch.float64
RGB_R = (0.9, 0.5, 0.1)


def direction(mu: float, phi: float = 0.0) -> Tensor:
    s = math.sqrt(max(0.0, 1.0 - mu * mu))
    return torch.tensor([s * math.cos(phi), s * math.sin(phi), mu], dtype=F64)


def scalar(x: float) -> Tensor:
    return torch.tensor([[x]], dtype=F64)


def metal(r: float = 0.5, g: float = 1.0) -> tuple[Tensor, Tensor]:
    """Gulbrandsen (n, k) of a grey reflectivity r, or of ``RGB_R`` for r < 0."""
    rr = torch.tensor([RGB_R], dtype=F64) if r < 0 else torch.full((1, 3), r, dtype=F64)
    return lobes.gulbrandsen(rr, torch.full((1, 3), g, dtype=F64))


def hemisphere_rule(n_cos: int = 256, n_phi: int = 256) -> tuple[Tensor, Tensor]:
    """Gauss-Legendre directions and weights over the upper hemisphere (sum 2 pi)."""
    x, w = np.polynomial.legendre.leggauss(n_cos)
    cos = torch.from_numpy((x + 1) / 2)
    w_cos = torch.from_numpy(w / 2)
    phi = (torch.arange(n_phi, dtype=F64) + 0.5) * 2 * math.pi / n_phi
    c, p = torch.meshgrid(cos, phi, indexing="ij")
    s = (1 - c ** 2).sqrt()
    dirs = torch.stack([s * p.cos(), s * p.sin(), c], -1).reshape(-1, 3)
    weights = (w_cos[:, None] * torch.full((n_phi,), 2 * math.pi / n_phi, dtype=F64)).reshape(-1, 1)
    return dirs, weights


def stratified(m: int) -> Tensor:
    t = (torch.arange(m, dtype=F64) + 0.5) / m
    return torch.stack(torch.meshgrid(t, t, indexing="ij"), -1).reshape(-1, 2)


def importance_integral(wi: Tensor, alpha: Tensor, f: Callable[[Tensor], Tensor], m: int = 192) -> Tensor:
    """int f(wo) dwo by VNDF importance sampling on a stratified grid."""
    u = stratified(m)
    wi = wi.expand(len(u), 3)
    wo = lobes.ggx_sample(wi, alpha, u)
    pdf = lobes.ggx_pdf(wi, wo, alpha)
    return torch.where(pdf > 0, f(wo) / pdf.clamp(min=1e-300), torch.zeros_like(f(wo))).mean(0)


def probe(closure: str, inputs: dict[str, graph.Value]) -> graph.Lobe:
    """A lobe of kind ``closure`` with constant ``inputs`` and weight ``dust_weight`` (1 in ``material``)."""
    return graph.Lobe("probe", closure, graph.Ref("dust_weight"), inputs)


def material(node: graph.Node, base_color: float = 0.0) -> LayeredBsdf:
    """A material of the graph ``node`` alone, with ``dust_weight`` 1 and a grey base colour."""
    return LayeredBsdf({"dust_weight": scalar(1.0)}, torch.full((1, 3), base_color, dtype=F64), node=node)


def sampler_chi2(node: graph.Lobe | graph.Diffuse, wi: Tensor, seed: int) -> Chi2Result:
    """Chi-square test of a closure kind's registered sampler against its registered pdf at one view direction."""
    bsdf = material(node)
    kind = TORCH[node.closure]

    def sample(n: int) -> Tensor:
        u = torch.rand(n, 2, generator=torch.Generator().manual_seed(seed), dtype=F64)
        wo = kind.sample(bsdf, node, wi.expand(n, 3), u, torch.arange(n))
        return torch.where(wo[:, 2:3] > 0, wo, torch.full_like(wo, math.nan))  # Cycles rejects these

    return chi2_test(sample, lambda wo: kind.pdf(bsdf, node, wi.expand_as(wo), wo)[:, 0])
