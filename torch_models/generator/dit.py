"""A small diffusion transformer over a stack of views (the CPU-sized stand-in for Cosmos).

Every view of the object is cut into p x p patches; one token per patch carries
the noisy 6 latent channels and the conditions of those pixels (world normal 3,
world position 3, base colour 3, roughness, metalness and whether they are known,
the uplift prior's latents 6, coverage 1: ``views.CONDITION_LAYOUT``), so the
geometry sits in every token, as the paper concatenates its condition latents
channel-wise. The model denoises the residual between the object's latents and
its uplift prior (``prior.py``): what the prompt's wording changes. Attention
is full across all views x patches: a texel seen in two views can agree with
itself. Tokens get a learned in-view patch position; views need no index because
their world positions say where they are. Noise level, text embedding and the
enhancement type enter every block through adaLN-Zero modulation (DiT).

A model conditions on the enhancement types of the table it was trained with
(``DitConfig.types``, read back from the weights of a checkpoint): type index
``types``, one past the last, and a zero text vector are the unconditional input of
classifier-free guidance, so a type added to the table later is refused by an
older model rather than read as the unconditional token.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Callable

import torch
from torch import Tensor, nn

from richmat_addon.core.enhancement_types import TYPES
from . import edm
from .views import CONDITION_CHANNELS, PBR_CHANNELS, PRIOR_CHANNELS

LATENT_CHANNELS = 6
TYPE_EMBEDDING = "net.type_embed.weight"  # its rows: one per type, then the unconditional token


@dataclass(frozen=True)
class DitConfig:
    size: int = 32  # view resolution (square)
    patch: int = 4
    dim: int = 128
    depth: int = 4
    heads: int = 4
    text_dim: int = 384
    sigma_data: float = edm.SIGMA_DATA  # the residual's scale: EDM's preconditioning and loss weighting
    p_mean: float = edm.P_MEAN  # centre of the training noise levels (ln sigma)
    sigma_max: float = edm.SIGMA_MAX  # where sampling starts
    types: int = len(TYPES)  # enhancement types conditioned on; index ``types`` is the unconditional token

    def to_dict(self) -> dict:
        return asdict(self)


def _modulate(x: Tensor, shift: Tensor, scale: Tensor) -> Tensor:
    return x * (1 + scale[:, None]) + shift[:, None]


class Block(nn.Module):
    """Pre-norm attention + MLP block with adaLN-Zero (the gates start at 0, so each block starts as identity)."""

    def __init__(self, dim: int, heads: int) -> None:
        super().__init__()
        self.heads = heads
        self.norm1 = nn.LayerNorm(dim, elementwise_affine=False, eps=1e-6)
        self.qkv = nn.Linear(dim, 3 * dim)
        self.proj = nn.Linear(dim, dim)
        self.norm2 = nn.LayerNorm(dim, elementwise_affine=False, eps=1e-6)
        self.mlp = nn.Sequential(nn.Linear(dim, 4 * dim), nn.GELU(approximate="tanh"), nn.Linear(4 * dim, dim))
        self.ada = nn.Linear(dim, 6 * dim)
        nn.init.zeros_(self.ada.weight)
        nn.init.zeros_(self.ada.bias)

    def _attention(self, h: Tensor) -> Tensor:
        """Full self-attention over all tokens (scaled_dot_product_attention: flash kernels on GPUs)."""
        b, n, d = h.shape
        q, k, v = self.qkv(h).reshape(b, n, 3, self.heads, d // self.heads).permute(2, 0, 3, 1, 4)
        out = nn.functional.scaled_dot_product_attention(q, k, v)
        return self.proj(out.transpose(1, 2).reshape(b, n, d))

    def forward(self, x: Tensor, c: Tensor) -> Tensor:
        s1, k1, g1, s2, k2, g2 = self.ada(nn.functional.silu(c)).chunk(6, -1)
        x = x + g1[:, None] * self._attention(_modulate(self.norm1(x), s1, k1))
        return x + g2[:, None] * self.mlp(_modulate(self.norm2(x), s2, k2))


class MultiViewDit(nn.Module):
    """F(c_in x, c_noise | conditions): the raw network that EDM preconditioning wraps."""

    def __init__(self, cfg: DitConfig) -> None:
        super().__init__()
        self.cfg = cfg
        grid = cfg.size // cfg.patch
        per_patch = cfg.patch * cfg.patch
        self.embed = nn.Linear((LATENT_CHANNELS + CONDITION_CHANNELS) * per_patch, cfg.dim)
        self.position = nn.Parameter(0.02 * torch.randn(grid * grid, cfg.dim))
        self.noise_features = edm.FourierFeatures(cfg.dim)
        self.noise_mlp = nn.Sequential(nn.Linear(cfg.dim, cfg.dim), nn.SiLU(), nn.Linear(cfg.dim, cfg.dim))
        self.text = nn.Linear(cfg.text_dim, cfg.dim)
        self.type_embed = nn.Embedding(cfg.types + 1, cfg.dim)
        self.blocks = nn.ModuleList(Block(cfg.dim, cfg.heads) for _ in range(cfg.depth))
        self.final_norm = nn.LayerNorm(cfg.dim, elementwise_affine=False, eps=1e-6)
        self.final_ada = nn.Linear(cfg.dim, 2 * cfg.dim)
        self.out = nn.Linear(cfg.dim, LATENT_CHANNELS * per_patch)
        for layer in (self.final_ada, self.out):
            nn.init.zeros_(layer.weight)
            nn.init.zeros_(layer.bias)

    def _patchify(self, x: Tensor) -> Tensor:
        """(B, V, C, H, W) -> (B, V * grid^2, C * p^2)."""
        b, v, c, h, w = x.shape
        p = self.cfg.patch
        x = x.reshape(b, v, c, h // p, p, w // p, p).permute(0, 1, 3, 5, 2, 4, 6)
        return x.reshape(b, v * (h // p) * (w // p), c * p * p)

    def _unpatchify(self, t: Tensor, v: int) -> Tensor:
        b, p, g = len(t), self.cfg.patch, self.cfg.size // self.cfg.patch
        t = t.reshape(b, v, g, g, LATENT_CHANNELS, p, p).permute(0, 1, 4, 2, 5, 3, 6)
        return t.reshape(b, v, LATENT_CHANNELS, g * p, g * p)

    def forward(self, x: Tensor, c_noise: Tensor, conditions: Tensor, text: Tensor, type_: Tensor) -> Tensor:
        """x (B, V, 6, H, W) already scaled by c_in; conditions (B, V, CONDITION_CHANNELS, H, W); text (B, text_dim); type_ (B,)."""
        v = x.shape[1]
        tokens = self.embed(self._patchify(torch.cat([x, conditions], 2)))
        tokens = tokens + self.position.repeat(v, 1)
        c = self.noise_mlp(self.noise_features(c_noise)) + self.text(text) + self.type_embed(type_)
        for block in self.blocks:
            tokens = block(tokens, c)
        shift, scale = self.final_ada(nn.functional.silu(c)).chunk(2, -1)
        return self._unpatchify(self.out(_modulate(self.final_norm(tokens), shift, scale)), v)


@dataclass
class Conditions:
    """What a generation is conditioned on, batched: views (B, V, CONDITION_CHANNELS, H, W), text (B, 384),
    type (B,); in training also the prior without roughness and metalness, ``unknown_prior`` (B, V, 6, H, W)."""

    views: Tensor
    text: Tensor
    type: Tensor
    unknown_prior: Tensor | None = None

    @property
    def prior(self) -> Tensor:
        """(B, V, 6, H, W) the uplift prior's latents the residual is added to."""
        return self.views[:, :, PRIOR_CHANNELS]

    def unconditional(self, null_type: int) -> "Conditions":
        """The same geometry and prior with the prompt dropped (zero text, the model's ``null_type``)."""
        return Conditions(self.views, torch.zeros_like(self.text), torch.full_like(self.type, null_type),
                          self.unknown_prior)

    def repeat(self, count: int) -> "Conditions":
        """Each sample ``count`` times in a row (several draws for the same conditions)."""
        rep = lambda t: None if t is None else t.repeat_interleave(count, 0)
        return Conditions(rep(self.views), rep(self.text), rep(self.type), rep(self.unknown_prior))

    def drop(self, keep: Tensor, null_type: int) -> "Conditions":
        """Per-sample prompt dropout for classifier-free guidance training; keep (B,) bool."""
        return Conditions(self.views, self.text * keep[:, None], torch.where(keep, self.type, null_type),
                          self.unknown_prior)

    def drop_pbr(self, keep: Tensor) -> "Conditions":
        """Per-sample dropout of the roughness and metalness maps (and their known flag), with the
        prior swapped for the one uplifted without them, so one model serves meshes that come with
        them and meshes that do not; keep (B,) bool."""
        assert self.unknown_prior is not None, "training conditions carry the unknown-PBR prior"
        views = self.views.clone()
        kept = keep[:, None, None, None, None]
        views[:, :, PBR_CHANNELS] *= kept.to(views.dtype)
        views[:, :, PRIOR_CHANNELS] = torch.where(kept, views[:, :, PRIOR_CHANNELS], self.unknown_prior)
        return Conditions(views, self.text, self.type, self.unknown_prior)


class LatentGenerator(nn.Module):
    """The preconditioned denoiser D(x; sigma | conditions) and the learned loss log-variance u(sigma)."""

    def __init__(self, cfg: DitConfig) -> None:
        super().__init__()
        self.net = MultiViewDit(cfg)
        self.logvar = edm.LogVariance()

    @property
    def null_type(self) -> int:
        """The type index of the unconditional input: one past the types the model was trained on."""
        return self.net.cfg.types

    def _check_types(self, cond: Conditions) -> None:
        if bool(((cond.type < 0) | (cond.type >= self.null_type)).any()):
            raise ValueError(f"this generator was trained on enhancement types 0-{self.null_type - 1} and is asked "
                             f"for {sorted(set(cond.type.tolist()))}: a type added to the table since needs a "
                             "generator trained with it (`python -m torch_models train-generator`)")

    def denoise(self, x: Tensor, sigma: Tensor, cond: Conditions) -> Tensor:
        """Estimate of the clean residual; background pixels (coverage 0) are forced to 0, as in the data."""
        s = edm.scalings(sigma.reshape(-1, 1, 1, 1, 1), self.net.cfg.sigma_data)
        f = self.net(s.c_in * x, s.c_noise.flatten(), cond.views, cond.text, cond.type)
        return (s.c_skip * x + s.c_out * f) * cond.views[:, :, -1:]

    def forward(self, target: Tensor, cond: Conditions, generator: torch.Generator, drop_prob: float = 0.1,
                pbr_drop_prob: float = 0.0) -> Tensor:
        """The training loss (forward, so DistributedDataParallel sees it) for latent views ``target``:
        a random noise level per sample, the prompt dropped with ``drop_prob``, the roughness and
        metalness maps (and the prior made with them) with ``pbr_drop_prob``; the model learns the
        residual target - prior. Randomness comes from the CPU ``generator``, so a run is
        reproducible on any device."""
        b, dev = len(target), target.device
        sigma = edm.sample_sigma(b, generator, self.net.cfg.p_mean).to(dev)
        noise = torch.randn(target.shape, generator=generator).to(dev)
        keep = (torch.rand(b, generator=generator) >= drop_prob).to(dev)
        keep_pbr = (torch.rand(b, generator=generator) >= pbr_drop_prob).to(dev)
        self._check_types(cond)
        cond = cond.drop(keep, self.null_type).drop_pbr(keep_pbr)
        x0 = target - cond.prior
        x0_pred = self.denoise(x0 + sigma.reshape(-1, 1, 1, 1, 1) * noise, sigma, cond)
        return edm.weighted_loss(x0, x0_pred, sigma, self.logvar(sigma), cond.views[:, :, -1:],
                                 self.net.cfg.sigma_data)

    @torch.no_grad()
    def sample(self, cond: Conditions, steps: int, seed: int, guidance: float = 1.0,
               progress: Callable[[int, int], None] | None = None, samples: int = 1) -> Tensor:
        """Residual latent views (B, V, 6, H, W) for the conditions, deterministic per seed: the
        object's latents are ``cond.prior`` plus these. ``samples`` > 1 draws that many in one batch
        and returns their mean, an estimate of the posterior mean (the least squared error)."""
        self._check_types(cond)
        cond = cond.repeat(samples)
        b, v, _, h, w = cond.views.shape
        noise = torch.randn((b, v, LATENT_CHANNELS, h, w),
                            generator=torch.Generator().manual_seed(seed)).to(cond.views.device)
        uncond = cond.unconditional(self.null_type)
        denoise = edm.guided(lambda x, s: self.denoise(x, s, cond), lambda x, s: self.denoise(x, s, uncond),
                             guidance)
        x = edm.heun_sample(denoise, noise, steps, progress, self.net.cfg.sigma_max)
        return x.reshape(b // samples, samples, *x.shape[1:]).mean(1)
