"""The hybrid decoder as a renderer's closures: every gate held constant over wo.

Cycles (and any renderer with its own light transport) takes a material as a
sum of closures whose weights may depend on the shading point and the view
direction, never on the light direction. The hybrid's head already has that
form (``HybridDecoder.head_at``: lobes and slot weights from (latent, wi)); its
gates do not, since they read both directions. This module replaces each gate
by one value per shading point, which is what the preview shader
(``richmat_addon/core/neural_osl_hybrid.py``) computes, so the torch renderer
can render exactly what Cycles renders, and benches can measure what the
replacement costs against the full decoder.

Rules (``RULES``):

* ``"dominant"``: each gate at its lobe's dominant direction: the mirror of wi
  for a GGX lobe, the normal for the diffuse and sheen lobes.
* ``"mean"``: each gate averaged over directions drawn from its own lobe
  (the GGX lobe's visible normals, the cosine lobe, the sheen's LTC), so the
  closure keeps the lobe's energy as the gates shaped it where the lobe has it.
  A draw below the horizon (a GGX lobe's, at grazing views) is mirrored above
  it, so every draw counts and the mean of any number of draws is unbiased.
  Like the shader, each evaluation draws ``draws`` directions per lobe, so a
  renderer's samples converge to the same average; fixed points (a
  quadrature) can be passed instead.
"""
from __future__ import annotations

import dataclasses
import math

import torch
from torch import Tensor, nn

from ...brdf.ggx import ggx_sample
from ...brdf.lobes import sheen_sample
from ..model import NeuralModel
from .networks import HybridDecoder, Lobes

RULES = ("dominant", "mean")


def stratified(n: int) -> Tensor:
    """(n * n, 2) cell centres of an n x n grid in [0, 1)^2."""
    c = (torch.arange(n, dtype=torch.float32) + 0.5) / n
    return torch.stack(torch.meshgrid(c, c, indexing="ij"), -1).reshape(-1, 2)


def _cosine(u: Tensor) -> Tensor:
    r, phi = u[:, :1].sqrt(), 2.0 * math.pi * u[:, 1:2]
    return torch.cat([r * phi.cos(), r * phi.sin(), (1.0 - u[:, :1]).clamp(min=0.0).sqrt()], -1)


class ClosureForm(nn.Module):
    """A hybrid decoder whose gates depend on (latent, wi) only: same interface, same lobes and T."""

    kind = "hybrid"

    def __init__(self, decoder: HybridDecoder, rule: str = "mean", draws: int = 2, seed: int = 0) -> None:
        super().__init__()
        if rule not in RULES:
            raise ValueError(f"unknown gate rule {rule!r}: one of {RULES}")
        self.decoder, self.rule, self.draws = decoder, rule, draws
        self.generator = torch.Generator().manual_seed(seed)
        self.lobes, self.sheen, self.t_slot = decoder.lobes, decoder.sheen, decoder.t_slot

    @property
    def bounded(self) -> bool:
        return self.decoder.bounded

    def gates_at(self, latent: Tensor, wi: Tensor, points: Tensor | None = None, lobes: Lobes | None = None) -> Tensor:
        """(N, slots, 3) one gate per lobe slot (GGX lobes, diffuse, [sheen]) at each point; for the mean,
        over ``points`` (m, 2) in [0, 1)^2 shared by all points, or ``draws`` random ones per point.
        ``lobes``: the head at (latent, wi) where the caller has it already."""
        d = self.decoder
        if d.view_gates:  # nothing to hold: the gates read wi alone
            return d.gates_at(latent, wi, wi)
        lobes = d.head_at(latent, wi) if lobes is None else lobes
        if self.rule == "dominant":  # the GGX lobes' gates at the mirror of wi, the others' at the normal
            normal = torch.zeros_like(wi)
            normal[:, 2] = 1.0
            mirror = wi * torch.tensor([-1.0, -1.0, 1.0])
            k = self.lobes
            return torch.cat([d.gates_at(latent, wi, mirror)[:, :k], d.gates_at(latent, wi, normal)[:, k:]], 1)
        n = len(wi)
        m = self.draws if points is None else len(points)
        u_m = torch.rand(n * m, 2, generator=self.generator) if points is None else points.repeat(n, 1)
        z_m, wi_m = latent.repeat_interleave(m, 0), wi.repeat_interleave(m, 0)
        out = []
        for k in range(self.lobes + 1 + self.sheen):
            if k < self.lobes:
                wo = ggx_sample(wi_m, lobes.alpha[:, k:k + 1].repeat_interleave(m, 0), u_m)
            elif k == self.lobes:
                wo = _cosine(u_m)
            else:
                wo = sheen_sample(wi_m, lobes.sheen_roughness.repeat_interleave(m, 0), u_m)
            wo = torch.cat([wo[:, :2], wo[:, 2:].abs()], -1)  # below the horizon: its mirror image above
            out.append(d.gates_at(z_m, wi_m, wo)[:, k].reshape(n, m, 3).mean(1))
        return torch.stack(out, 1)

    def forward(self, latent: Tensor, wi: Tensor, wo: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        lobes = self.decoder.head_at(latent, wi)
        f = self.decoder.lobe_sum(lobes, latent, wi, wo, gates=self.gates_at(latent, wi, lobes=lobes))
        return f, lobes.weights[:, self.t_slot:self.t_slot + 1], lobes.r


def closure_model(model: NeuralModel) -> NeuralModel:
    """``model`` with its decoder replaced by its closure form (the mean rule): what the preview renders."""
    return dataclasses.replace(model, decoder=ClosureForm(model.decoder))
