"""The losses every decoder kind is trained (and its latents fitted) with.

``decoder_loss`` compares log(1 + f cos) per channel with the analytic target
(f spans ten decades), plus a chroma term: while the grey error exceeds the
colour difference, per-channel L1 gives all three channels the same sign of
gradient, and a decoder trained with L1 alone decoded every metal grey.
``albedo_loss`` ties the integral of f_neu to the analytic albedo, which the
per-pair loss does not.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import Tensor

from ..brdf.model import LayeredBsdf, luminance, params_from_vectors
from .data import Batch, view_directions
from .networks import MAX_LOG_F, DecoderNet, f_cos

LOSS_WEIGHTS = (0.95, 0.04, 0.01)  # f, T, R (paper sec. 4)
RELATIVE_EPS = 0.005  # f cos below this counts as zero in decoder_loss's relative term
CHROMA_WEIGHT = 10.0


def decoder_loss(dec: DecoderNet, z: Tensor, batch: Batch, chroma_weight: float = CHROMA_WEIGHT,
                 relative_weight: float = 0.0, t_weight: float = LOSS_WEIGHTS[1]) -> Tensor:
    """The training (and fitting) loss of latents z against a batch of analytic targets.

    ``relative_weight`` adds L1 in log(RELATIVE_EPS + f cos): log(1 + f cos) weighs an
    error absolutely wherever f cos < 1, so a broad lobe of f cos ~ 0.05 (a metal's haze
    or dust sheen, which lights the whole ball) can be half wrong at the cost of a
    highlight's rounding; the term makes relative error count down to RELATIVE_EPS."""
    y, t, r = dec.log_forward(z, batch.wi, batch.wo)
    target = batch.f.clamp(max=math.expm1(MAX_LOG_F))
    err = y - torch.log1p(target)
    chroma = err - err.mean(-1, keepdim=True)
    f_loss = err.abs().mean() + chroma_weight * chroma.pow(2).mean()
    if relative_weight:
        relative = (RELATIVE_EPS + f_cos(y)).log() - (RELATIVE_EPS + target).log()
        f_loss = f_loss + relative_weight * relative.abs().mean()
    wf, _, wr = LOSS_WEIGHTS
    return wf * f_loss + t_weight * (t - batch.t).abs().mean() + wr * (r - batch.r).abs().mean()


def albedo_loss(dec: DecoderNet, z: Tensor, vectors: Tensor, n: int, gen: torch.Generator) -> Tensor:
    """Squared relative error of the directional albedo (luminance) of f_neu at latents z (K, 6)
    against the analytic R(wi) of their parameter vectors (K, 22), one random view angle each.

    The albedo is estimated from n wo sampled from the analytic lobes (exact pdf): unbiased,
    so the squared error's gradient is unbiased up to the estimate's variance, which the
    0.05 in the denominator keeps from dominating dark materials."""
    k = len(z)
    s = lobe_samples(vectors.to(z.device), n, gen)
    with torch.no_grad():
        target = s.bsdf.reflectance(s.wi)[::n, 0]
    f, _, _ = dec(z.repeat_interleave(n, 0), s.wi, s.wo)
    est = torch.where(s.ok, luminance(f)[:, 0] / s.pdf.clamp(min=1e-6), torch.zeros_like(f[:, 0]))
    return (((est.reshape(k, n).mean(1) - target) / (target + 0.05)) ** 2).mean()


@dataclass
class LobeSamples:
    """n outgoing directions per material, importance-sampled from its analytic lobes at one
    random view angle: the material at every sample, wi and wo (K n, 3), the exact pdf
    (K n,) and where the estimate may divide by it (above the horizon, pdf > 1e-6)."""

    bsdf: LayeredBsdf
    wi: Tensor
    wo: Tensor
    pdf: Tensor
    ok: Tensor


def lobe_samples(vectors: Tensor, n: int, gen: torch.Generator) -> LobeSamples:
    """``LobeSamples`` of materials (K, 22), view cosines uniform in [0.05, 1], on the vectors'
    device (a GPU run would otherwise spend most of each step here); the random numbers come
    from the CPU generator ``gen``, so a run draws the same samples on either device."""
    k, device = len(vectors), vectors.device
    mu = 0.05 + 0.95 * torch.rand(k, 1, generator=gen)
    wi = view_directions(mu.to(device)).repeat_interleave(n, 0)
    with torch.no_grad():
        bsdf = LayeredBsdf(params_from_vectors(vectors.repeat_interleave(n, 0)), torch.ones(1, 3, device=device))
        wo = bsdf.sample(wi, torch.rand(k * n, 3, generator=gen).to(device))
        pdf = bsdf.pdf(wi, wo)
    return LobeSamples(bsdf, wi, wo, pdf, (wo[:, 2] > 0) & (pdf > 1e-6))
