"""What every decoder kind shares: the encoder, the direction features, MLP layers.

- ``Encoder``: the 22 material parameters (normalised to [0, 1] by the schema's
  bounds) to a 6D latent in the box (-1, 1)^6 (tanh), so generated and perturbed
  latents have a known range. Training keeps the pre-activation inside +-2
  (``saturation``): a saturated tanh passes no gradient.
- ``direction_features``: wi, wo, the half vector and wi.h (local frame, z = shading
  normal): the specular peak is a simple function of h, which plain wi/wo inputs make
  a small MLP learn the hard way.
- ``f_cos``: decoders are trained on y = log(1 + f * cos), the quantity the loss
  compares; f * cos = max(exp(min(y, 12)) - 1, 0).
- ``DecoderNet``, ``Sampler``: what every kind's decoder and importance sampler offer.
"""
from __future__ import annotations

from typing import Protocol

import torch
from torch import Tensor, nn

from richmat_addon.core.schema import bounds

LATENT = 6
MAX_LOG_F = 12.0  # exp(12) ~ 1.6e5: above any f*cos a GGX lobe with alpha >= 1e-2 reaches
SATURATION = 2.0  # encoder pre-activations beyond +-2 are penalised in training (tanh(2) = 0.96)


def mlp(n_in: int, width: int, depth: int, n_out: int) -> nn.Sequential:
    """Linear layers with ReLU between them; the ReLU works in place (a fresh activation tensor
    per layer costs more than the ReLU itself on a CPU at batch 16k)."""
    layers: list[nn.Module] = []
    for k in range(depth):
        layers += [nn.Linear(n_in if k == 0 else width, width), nn.ReLU(inplace=True)]
    layers.append(nn.Linear(width if depth else n_in, n_out))
    return nn.Sequential(*layers)


def normalise_params(vectors: Tensor) -> Tensor:
    """Packed (N, 22) schema vectors mapped to [0, 1] by the schema's bounds."""
    lo, hi = (torch.tensor(b, dtype=vectors.dtype, device=vectors.device) for b in bounds())
    return (vectors - lo) / (hi - lo)


DIRECTION_FEATURES = 10  # wi, wo, h, wi.h


def direction_features(wi: Tensor, wo: Tensor) -> Tensor:
    h = wi + wo
    h = h / h.norm(dim=-1, keepdim=True).clamp(min=1e-12)
    return torch.cat([wi, wo, h, (wi * h).sum(-1, keepdim=True)], -1)


class Encoder(nn.Module):
    def __init__(self, width: int = 64, depth: int = 3) -> None:
        super().__init__()
        self.net = mlp(len(bounds()[0]), width, depth, LATENT)

    def pre_activation(self, vectors: Tensor) -> Tensor:
        return self.net(normalise_params(vectors))

    def forward(self, vectors: Tensor) -> Tensor:
        return torch.tanh(self.pre_activation(vectors))


def saturation(pre_activation: Tensor) -> Tensor:
    """Mean squared excess of encoder pre-activations beyond +-SATURATION: the training penalty."""
    return torch.relu(pre_activation.abs() - SATURATION).pow(2).mean()


def f_cos(y: Tensor) -> Tensor:
    """f_neu * cos from the decoder's log output y = log(1 + f * cos), clamped at the ceiling."""
    return (torch.exp(y.clamp(max=MAX_LOG_F)) - 1.0).clamp(min=0.0)


class DecoderNet(Protocol):
    """f_neu * cos (N, 3), T (N, 1), R (N, 1) from latents (N, 6) and local directions (N, 3)."""

    kind: str  # the name of its entry in ``kinds.KINDS``
    bounded: bool  # albedo(f_neu) + T <= 1 for every latent: fits need no furnace repair

    def __call__(self, latent: Tensor, wi: Tensor, wo: Tensor) -> tuple[Tensor, Tensor, Tensor]: ...

    def log_forward(self, latent: Tensor, wi: Tensor, wo: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        """(log(1 + f * cos), T, R): what the training loss compares."""
        ...


class Sampler(Protocol):
    """Importance sampling of a decoder's f_neu at a latent: wo from u (N, 3), and its pdf."""

    def pdf(self, latent: Tensor, wi: Tensor, wo: Tensor) -> Tensor: ...

    def sample(self, latent: Tensor, wi: Tensor, u: Tensor) -> Tensor: ...
