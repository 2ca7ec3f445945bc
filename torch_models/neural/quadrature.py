"""A deterministic half-vector quadrature of a decoder's directional albedo.

Monte Carlo estimates of a lobe narrower than the sampler's are heavy-tailed; a
quadrature over half vectors, dense around the normal, is not. wo = reflect(wi, h)
maps the half-vector hemisphere onto every outgoing direction.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import Tensor

from .data import view_directions
from .model import NeuralModel

VIEW_COSINES = (1.0, 0.7, 0.4, 0.15, 0.05)
QUADRATURE_THETA = 64  # half-vector polar rings
QUADRATURE_PHI = 32  # azimuths per ring: a lobe around the mirror direction sits at h = n for every wi,
# where rings are tiny, so polar resolution buys accuracy and azimuths mostly cost (10 k evaluations per latent)


def half_vector_grid(n_theta: int = QUADRATURE_THETA, n_phi: int = QUADRATURE_PHI) -> tuple[Tensor, Tensor]:
    """Midpoint quadrature nodes h (M, 3) on the upper hemisphere and their solid angles (M,).

    Polar angle theta_h = (pi / 2) t^3 for uniform t: rings crowd around the normal,
    where a narrow lobe's half vectors are (the innermost rings resolve alpha ~ 1e-3)."""
    t = (torch.arange(n_theta, dtype=torch.float64) + 0.5) / n_theta
    theta = 0.5 * math.pi * t ** 3
    d_theta = 1.5 * math.pi * t ** 2 / n_theta
    phi = (torch.arange(n_phi, dtype=torch.float64) + 0.5) * 2 * math.pi / n_phi
    th, ph = torch.meshgrid(theta, phi, indexing="ij")
    h = torch.stack([th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()], -1).reshape(-1, 3)
    d_omega = (th.sin() * d_theta[:, None] * (2 * math.pi / n_phi)).reshape(-1)
    return h.float(), d_omega.float()


def half_vector_nodes(mu: float, n_theta: int = QUADRATURE_THETA,
                      n_phi: int = QUADRATURE_PHI) -> tuple[Tensor, Tensor, Tensor]:
    """wi (3,) at view cosine ``mu``, outgoing directions wo (M, 3) and weights (M,) such that
    sum(weights * g(wi, wo)) integrates g over the outgoing hemisphere.

    wo = reflect(wi, h) maps the half-vector hemisphere onto all outgoing directions
    with d omega_o = 4 (wi . h) d omega_h; those below the horizon get weight 0."""
    h, d_omega = half_vector_grid(n_theta, n_phi)
    wi = view_directions(torch.tensor([[mu]]))[0]
    cos_h = h @ wi
    wo = 2 * cos_h[:, None] * h - wi
    weight = torch.where((cos_h > 0) & (wo[:, 2] > 0), 4 * cos_h * d_omega, torch.zeros_like(cos_h))
    return wi, wo, weight


@dataclass
class QuadratureSums:
    """The half-vector quadrature of K latents (at ``VIEW_COSINES``, or one view): f_neu's albedo
    per colour channel, unscaled, (K, [A,] 3), and the diffuse base's T / pi, (K, [A])."""

    reflected: Tensor
    diffuse: Tensor

    def albedo(self, scale: Tensor | None = None) -> Tensor:
        """The brightest channel's albedo of s f_neu + T / pi (s = 1 when None): linear in s,
        so a repaired latent needs no second quadrature."""
        reflected = self.reflected
        if scale is not None:
            reflected = reflected * scale.reshape((-1,) + (1,) * (reflected.dim() - 1))
        return (reflected + self.diffuse[..., None]).amax(-1)

    def __getitem__(self, index: Tensor) -> QuadratureSums:
        return QuadratureSums(self.reflected[index], self.diffuse[index])


def half_vector_albedo(model: NeuralModel, z: Tensor, n_theta: int = QUADRATURE_THETA,
                       n_phi: int = QUADRATURE_PHI, chunk: int = 1 << 18) -> QuadratureSums:
    """By quadrature at ``VIEW_COSINES``: f_neu's albedo per channel and the diffuse base's.

    T comes out of the same network as f, so it varies a little with wo, as the
    renderer evaluates it: the diffuse base is integrated too, not taken at one wo."""
    reflected, diffuse = torch.zeros(len(z), len(VIEW_COSINES), 3), torch.zeros(len(z), len(VIEW_COSINES))
    with torch.no_grad():
        for a, mu in enumerate(VIEW_COSINES):
            wi, wo, weight = half_vector_nodes(mu, n_theta, n_phi)
            per_chunk = max(1, chunk // len(wo))
            for k0 in range(0, len(z), per_chunk):
                k = slice(k0, k0 + per_chunk)
                sums = summed_albedo(model, z[k], wi, wo, weight)
                reflected[k, a], diffuse[k, a] = sums.reflected, sums.diffuse
    return QuadratureSums(reflected, diffuse)


def summed_albedo(model: NeuralModel, z: Tensor, wi: Tensor, wo: Tensor, weight: Tensor) -> QuadratureSums:
    """At one wi, the weighted sums over the outgoing nodes wo (M, 3): f_neu's albedo (K, 3)
    and the diffuse base's (K,)."""
    k, m = len(z), len(wo)
    f, t, _ = model.decoder(z.repeat_interleave(m, 0), wi.expand(k * m, 3), wo.repeat(k, 1))
    reflected = (f.reshape(k, m, 3) * weight[None, :, None]).sum(1)
    diffuse = (t.reshape(k, m) * wo[:, 2] * weight).sum(1) / math.pi
    return QuadratureSums(reflected, diffuse)
