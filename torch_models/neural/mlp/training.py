"""The MLP's training phases after the shared decoder phase (paper sec. 4).

Phase 2 goes on with an energy penalty on latents no material maps to (uniform in
the enlarged training latent box, and encoded latents perturbed by ten times the
jitter), so generated or edited latents do not gain energy. Phase 3 trains the
sampling decoder against the frozen decoder's luminance with the score-function
estimate of the forward KL divergence (Zeltner et al.).
"""
from __future__ import annotations

import math
from typing import cast

import torch
from torch import Tensor, nn

from ...distributed import data_parallel
from ...brdf.model import luminance
from ..data import cosine_hemisphere, view_directions
from ..decoder_kind import Phase, TrainingRun
from ..networks import DecoderNet
from ..validity import enlarged
from .config import MlpConfig
from .networks import SamplingDecoder

SAMPLER_LR = 1e-3


def energy_penalty(dec: DecoderNet, z: Tensor, n: int, gen: torch.Generator) -> Tensor:
    """Mean white-furnace gain, sum over channels of max(0, albedo - 1), of latents z (M, 6).

    Each latent gets one view direction (cos theta in [0.05, 1]) and n cosine-sampled
    wo; the albedo of f_neu + T * white Lambertian is estimated per channel.
    """
    m = len(z)
    wi = view_directions(0.05 + 0.95 * torch.rand(m, 1, generator=gen)).repeat_interleave(n, 0)
    wi, wo = wi.to(z.device), cosine_hemisphere(m * n, gen).to(z.device)
    f, t, _ = dec(z.repeat_interleave(n, 0), wi, wo)
    albedo = (f * (math.pi / wo[:, 2:3]) + t).reshape(m, n, 3).mean(1)
    return torch.relu(albedo - 1.0).sum(-1).mean()


def sampler_loss(sampler: SamplingDecoder, dec: DecoderNet, z: Tensor, wi: Tensor, u: Tensor) -> Tensor:
    """-E[target / pdf * log pdf] with wo from the (detached) sampler: the forward KL's gradient."""
    with torch.no_grad():
        wo = sampler.sample(z, wi, u)
        target = luminance(dec(z, wi, wo)[0]).squeeze(-1)
    pdf = sampler.pdf(z, wi, wo)
    ok = (wo[:, 2] > 0) & (pdf > 0)
    weight = torch.where(ok, target / pdf.detach().clamp(min=1e-4), torch.zeros_like(target))
    return -(weight * pdf.clamp(min=1e-4).log()).mean()


def odd_latents(z: Tensor, box: tuple[Tensor, Tensor], n: int, gen: torch.Generator) -> Tensor:
    """Latents no training material maps to: n uniform in the (enlarged) training latent
    box, n encoded latents perturbed by +-0.05 (ten times the jitter)."""
    lo, hi = box
    uniform = lo + (hi - lo) * torch.rand(n, len(lo), generator=gen).to(z.device)
    perturbed = z[:n] + 0.05 * (2 * torch.rand(n, z.shape[1], generator=gen) - 1).to(z.device)
    return torch.cat([uniform, perturbed])


class SamplerObjective(nn.Module):
    """Phase 3 as one module call, so DistributedDataParallel averages the sampler's gradients
    (the decoder stays frozen and outside the module)."""

    def __init__(self, sampler: SamplingDecoder) -> None:
        super().__init__()
        self.sampler = sampler

    def forward(self, decoder: DecoderNet, z: Tensor, wi: Tensor, u: Tensor) -> Tensor:
        return sampler_loss(self.sampler, decoder, z, wi, u)


def phases(run: TrainingRun) -> list[Phase]:
    """Decoder, energy (a low constant rate plus the penalty), sampler."""
    cfg, sampler = cast(MlpConfig, run.cfg), cast(SamplingDecoder, run.sampler)
    box: list[tuple[Tensor, Tensor]] = []  # the training latent box, fixed when phase 2 starts

    def latent_box() -> tuple[Tensor, Tensor]:
        """The encoded pool's bounding box enlarged by 10 %."""
        if not box:
            with torch.no_grad():
                pool_z = run.encoder(run.pool.to(run.where.device))
            box.append(enlarged((pool_z.min(0).values, pool_z.max(0).values), 1.1))
        return box[0]

    def penalty(decoder: DecoderNet, z: Tensor, gen: torch.Generator) -> Tensor:
        odd = odd_latents(z.detach(), latent_box(), cfg.energy_latents // 2, gen)
        return cfg.energy_weight * energy_penalty(decoder, odd, cfg.energy_samples, gen)

    objective = data_parallel(SamplerObjective(sampler), run.where)
    opt = torch.optim.Adam(sampler.parameters(), lr=SAMPLER_LR)

    def sampler_step() -> float:
        batch = run.buffered_batch()
        with torch.no_grad():
            z = run.encoder(batch.vectors)
        u = torch.rand(len(z), 3, generator=run.gen).to(z.device)
        loss = objective(run.decoder, z, batch.wi, u)
        opt.zero_grad()
        loss.backward()
        opt.step()
        return loss.item()

    return [Phase("decoder", cfg.steps, run.decoder_step),
            Phase("energy", cfg.energy_steps, lambda: run.decoder_step(lr=5 * cfg.lr_final, penalty=penalty)),
            Phase("sampler", cfg.sampler_steps, sampler_step)]
