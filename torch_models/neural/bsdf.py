"""A fitted neural material as a renderer BSDF: f = s f_neu + T(wi) c / pi.

f_neu and T come from the frozen decoder at the point's latent (s is the
material's energy scale, 1 unless the furnace repaired it). Optional glints
(``glints.py``) multiply f_neu per shading point and per RGB channel; sampling
ignores them, which keeps the estimator unbiased. Sampling mixes the
sampling decoder (for f_neu) with a cosine lobe (for the diffuse base) in
proportion to R(wi) and T(wi) lum(c), the same split the analytic model makes.
"""
from __future__ import annotations

import math

import torch
from torch import Tensor

from ..brdf.model import luminance
from .glints import Glints
from .model import NeuralModel


class NeuralBsdf:
    def __init__(self, model: NeuralModel, latent: Tensor, base_color: Tensor, energy_scale: float | Tensor = 1.0,
                 glints: Glints | None = None):
        self.model, self.latent, self.base_color = model, latent, base_color
        self.energy_scale, self.glints = energy_scale, glints
        self._cached: tuple[Tensor, tuple[Tensor, Tensor, Tensor]] | None = None

    def _z(self, n: int) -> Tensor:
        return self.latent.expand(n, -1) if self.latent.shape[0] == 1 else self.latent

    def _weights(self, wi: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        """T (N, 1), R (N, 1) and the probability of sampling the diffuse base (N, 1).

        The renderer asks for them twice per view direction (pdf and sample): the
        last answer is kept, keyed by the wi tensor itself.
        """
        if self._cached is not None and self._cached[0] is wi:
            return self._cached[1]
        _, t, r = self.model.decoder(self._z(len(wi)), wi, wi)
        diffuse = t * luminance(self.base_color.expand(len(wi), 3))
        p_diffuse = torch.where(diffuse + r > 0, diffuse / (diffuse + r).clamp(min=1e-12), torch.full_like(r, 0.5))
        self._cached = (wi, (t, r, p_diffuse))
        return t, r, p_diffuse

    def eval(self, wi: Tensor, wo: Tensor) -> Tensor:
        f, t, _ = self.model.decoder(self._z(len(wi)), wi, wo)
        cos_o = wo[:, 2:3].clamp(min=0.0) * (wi[:, 2:3] > 0)
        if self.glints is not None:
            f = f * self.glints(wi, wo)
        return self.energy_scale * f + t * self.base_color * cos_o / math.pi

    def pdf(self, wi: Tensor, wo: Tensor) -> Tensor:
        _, _, p_d = self._weights(wi)
        cosine = wo[:, 2].clamp(min=0.0) / math.pi
        return p_d[:, 0] * cosine + (1 - p_d[:, 0]) * self.model.sampler.pdf(self._z(len(wi)), wi, wo)

    def sample(self, wi: Tensor, u: Tensor) -> Tensor:
        _, _, p_d = self._weights(wi)
        r, phi = u[:, 1:2].sqrt(), 2 * math.pi * u[:, 2:3]
        cosine = torch.cat([r * phi.cos(), r * phi.sin(), (1 - u[:, 1:2]).clamp(min=0).sqrt()], -1)
        # Reuse u[:, 0] inside the sampler's own component choice, rescaled to [0, 1).
        u_glossy = torch.cat([((u[:, :1] - p_d) / (1 - p_d).clamp(min=1e-12)).clamp(0, 1 - 1e-7), u[:, 1:]], -1)
        glossy = self.model.sampler.sample(self._z(len(wi)), wi, u_glossy)
        return torch.where(u[:, :1] < p_d, cosine, glossy)
