"""EDM preconditioning, the EDM2/Cosmos uncertainty-weighted loss and a Heun sampler.

Karras et al. 2022 preconditioning with sigma_data = 0.5 and c_noise = ln(sigma) / 4
(Cosmos' choice); training noise levels ln sigma ~ N(-1.2, 1.2). The loss is the
EDM loss weighted by lambda(sigma) = (sigma^2 + sigma_data^2) / (sigma sigma_data)^2,
divided by exp(u(sigma)) and plus u(sigma), with u a learned log-variance of the
noise level (EDM2 eq. 21): the network learns how hard each noise level is, and
no level dominates the gradient. Sampling is the deterministic 2nd-order Heun
solver on Karras' rho = 7 schedule, with classifier-free guidance.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import torch
from torch import Tensor, nn

SIGMA_DATA = 0.5
P_MEAN, P_STD = -1.2, 1.2
SIGMA_MIN, SIGMA_MAX, RHO = 0.002, 80.0, 7.0


@dataclass(frozen=True)
class Scalings:
    c_skip: Tensor
    c_out: Tensor
    c_in: Tensor
    c_noise: Tensor


def scalings(sigma: Tensor, sigma_data: float = SIGMA_DATA) -> Scalings:
    """The EDM preconditioning factors for noise levels ``sigma`` (any shape)."""
    total = sigma ** 2 + sigma_data ** 2
    return Scalings(c_skip=sigma_data ** 2 / total, c_out=sigma * sigma_data / total.sqrt(),
                    c_in=1.0 / total.sqrt(), c_noise=0.25 * sigma.log())


def loss_weight(sigma: Tensor, sigma_data: float = SIGMA_DATA) -> Tensor:
    """lambda(sigma): makes the effective training target unit-variance at every level."""
    return (sigma ** 2 + sigma_data ** 2) / (sigma * sigma_data) ** 2


def sample_sigma(n: int, generator: torch.Generator | None = None, p_mean: float = P_MEAN) -> Tensor:
    """Training noise levels, log-normal around exp(p_mean)."""
    return (p_mean + P_STD * torch.randn(n, generator=generator)).exp()


class FourierFeatures(nn.Module):
    """Random Fourier features of a scalar (frozen), as EDM2 embeds the noise level."""

    def __init__(self, channels: int, seed: int = 0) -> None:
        super().__init__()
        gen = torch.Generator().manual_seed(seed)
        self.register_buffer("freqs", 2 * math.pi * torch.randn(channels, generator=gen))
        self.register_buffer("phases", 2 * math.pi * torch.rand(channels, generator=gen))

    def forward(self, x: Tensor) -> Tensor:
        return math.sqrt(2) * torch.cos(x[:, None] * self.freqs + self.phases)


class LogVariance(nn.Module):
    """u(sigma) of the uncertainty weighting: Linear(FourierFeatures(c_noise)), no bias, zero-initialised."""

    def __init__(self, channels: int = 128) -> None:
        super().__init__()
        self.features = FourierFeatures(channels, seed=1)
        self.linear = nn.Linear(channels, 1, bias=False)
        nn.init.zeros_(self.linear.weight)

    def forward(self, sigma: Tensor) -> Tensor:
        return self.linear(self.features(0.25 * sigma.log()))[:, 0]


Denoiser = Callable[[Tensor, Tensor], Tensor]  # (x_noisy, sigma) -> x0 estimate


def weighted_loss(x0: Tensor, x0_pred: Tensor, sigma: Tensor, logvar: Tensor, mask: Tensor,
                  sigma_data: float = SIGMA_DATA) -> Tensor:
    """Mean over the batch of lambda(sigma) * masked MSE / exp(u) + u.

    x0, x0_pred: (B, ...); mask broadcastable to them (1 where the object is), so the
    empty background neither helps nor hurts; sigma, logvar: (B,).
    """
    mask = mask.expand_as(x0)
    err = ((x0_pred - x0) ** 2 * mask).flatten(1).sum(1) / mask.flatten(1).sum(1).clamp(min=1.0)
    return (loss_weight(sigma, sigma_data) * err * torch.exp(-logvar) + logvar).mean()


def karras_sigmas(steps: int, sigma_min: float = SIGMA_MIN, sigma_max: float = SIGMA_MAX,
                  rho: float = RHO) -> Tensor:
    """``steps`` decreasing noise levels, then 0."""
    ramp = torch.linspace(0, 1, steps, dtype=torch.float64)
    s = (sigma_max ** (1 / rho) + ramp * (sigma_min ** (1 / rho) - sigma_max ** (1 / rho))) ** rho
    return torch.cat([s, torch.zeros(1, dtype=torch.float64)]).float()


def guided(cond: Denoiser, uncond: Denoiser, scale: float) -> Denoiser:
    """Classifier-free guidance: uncond + scale (cond - uncond); scale 1 is the conditional model
    itself, which needs no unconditional pass (half the network evaluations)."""
    if scale == 1.0:
        return cond

    def denoise(x: Tensor, sigma: Tensor) -> Tensor:
        d_uncond = uncond(x, sigma)
        return d_uncond + scale * (cond(x, sigma) - d_uncond)
    return denoise


@torch.no_grad()
def heun_sample(denoise: Denoiser, noise: Tensor, steps: int,
                progress: Callable[[int, int], None] | None = None, sigma_max: float = SIGMA_MAX) -> Tensor:
    """Deterministic EDM sampler (Karras et al. 2022, Alg. 1): Euler step plus Heun correction
    except into sigma = 0. ``noise`` is unit Gaussian; it is scaled to sigma_max here.
    ``progress(step, steps)`` is called after each step (the add-on's progress bar)."""
    sigmas = karras_sigmas(steps, sigma_max=sigma_max).to(noise.dtype)
    x = noise * sigmas[0]
    for k in range(steps):
        s, s_next = sigmas[k], sigmas[k + 1]
        batch = torch.full((len(x),), float(s), dtype=x.dtype)
        d = (x - denoise(x, batch)) / s
        x_next = x + (s_next - s) * d
        if s_next > 0:
            batch_next = torch.full((len(x),), float(s_next), dtype=x.dtype)
            d_next = (x_next - denoise(x_next, batch_next)) / s_next
            x_next = x + (s_next - s) * 0.5 * (d + d_next)
        x = x_next
        if progress is not None:
            progress(k + 1, steps)
    return x
