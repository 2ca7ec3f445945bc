"""The Lambertian base in torch: cos / pi of the base colour, cosine sampling; its albedo is 1."""
from __future__ import annotations

import math

import torch
from torch import Tensor

from richmat_addon.core import graph

from .kind import Material, TorchClosure


def _eval(m: Material, node: graph.Diffuse, wi: Tensor, wo: Tensor) -> Tensor:
    return wo[..., 2:3].clamp(min=0.0) * (wi[..., 2:3] > 0) / math.pi


def _albedo(m: Material, node: graph.Diffuse, cos_i: Tensor) -> Tensor:
    return torch.ones_like(cos_i)


def _sample(m: Material, node: graph.Diffuse, wi: Tensor, u: Tensor, rows: Tensor) -> Tensor:
    r = u[..., 0].sqrt()
    phi = 2.0 * math.pi * u[..., 1]
    z = (1.0 - u[..., 0]).clamp(min=0.0).sqrt()
    return torch.stack([r * phi.cos(), r * phi.sin(), z], dim=-1)


def _pdf(m: Material, node: graph.Diffuse, wi: Tensor, wo: Tensor) -> Tensor:
    return wo[..., 2:3].clamp(min=0.0) / math.pi


def _colour(m: Material, node: graph.Diffuse) -> Tensor:
    return m.base_color


IMPLEMENTATION = TorchClosure(_eval, _albedo, _sample, _pdf, _colour)
