"""The paper's direct decoder (sec. 4) and its trained sampling decoder.

- ``Decoder``: latent + direction features to f_neu * cos(theta_o) (RGB), T(wi)
  (sigmoid) and R(wi) (sigmoid). Its f outputs are y = log(1 + f * cos)
  (``networks.f_cos``): a plain exp output trained through log(1 + exp(y)) has a
  gradient that vanishes wherever f is small, most of the hemisphere. T and R depend
  on wi only but share the network: they are read at any wo.
- ``SamplingDecoder``: latent + wi to a two-component analytic mixture, a tilted
  cosine lobe and an anisotropic, sheared, offset GGX lobe in slope space
  (Zeltner et al. 2024), with an exact pdf.
"""
from __future__ import annotations

import math

import torch
from torch import Tensor, nn

from ..networks import DIRECTION_FEATURES, LATENT, direction_features, f_cos, mlp


class Decoder(nn.Module):
    """f_neu * cos (N, 3), T (N, 1), R (N, 1) from latents (N, 6) and directions (N, 3)."""

    kind = "mlp"
    bounded = False  # some latents gain energy: fitted ones go through the furnace (mlp.energy)

    def __init__(self, width: int, depth: int) -> None:
        """Size from the run's config (``mlp.config.MlpConfig``)."""
        super().__init__()
        self.width, self.depth = width, depth
        self.net = mlp(LATENT + DIRECTION_FEATURES, width, depth, 5)

    def log_forward(self, latent: Tensor, wi: Tensor, wo: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        """(log(1 + f * cos) before the horizon mask, T, R): what training compares with targets."""
        out = self.net(torch.cat([latent, direction_features(wi, wo)], -1))
        return out[:, :3], torch.sigmoid(out[:, 3:4]), torch.sigmoid(out[:, 4:5])

    def forward(self, latent: Tensor, wi: Tensor, wo: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        y, t, r = self.log_forward(latent, wi, wo)
        above = ((wi[:, 2:3] > 0) & (wo[:, 2:3] > 0)).to(y.dtype)
        return f_cos(y) * above, t, r


def _tanh_approx(x: Tensor) -> Tensor:
    return x / (1.0 + x * x).sqrt()


def _sinh_approx(x: Tensor) -> Tensor:
    return x * (1.0 + x * x).sqrt()


class SamplingDecoder(nn.Module):
    """Mixture parameters from (latent, wi); ``sample`` and ``pdf`` of wo."""

    def __init__(self, width: int = 32, depth: int = 2) -> None:
        super().__init__()
        # logits (2), diffuse tilt (2), GGX alpha (2), correlation (1), GGX slope offset (2)
        self.net = mlp(LATENT + 3, width, depth, 9)

    def mixture(self, latent: Tensor, wi: Tensor) -> dict[str, Tensor]:
        o = self.net(torch.cat([latent, wi], -1))
        return {"weights": torch.softmax(o[:, 0:2], -1), "tilt": _sinh_approx(o[:, 2:4]),
                "alpha": 1e-3 + 0.5 * (1.0 + _tanh_approx(o[:, 4:6])),
                "rho": 0.99 * _tanh_approx(o[:, 6:7]), "offset": _sinh_approx(o[:, 7:9])}

    def pdf(self, latent: Tensor, wi: Tensor, wo: Tensor) -> Tensor:
        m = self.mixture(latent, wi)
        p = m["weights"][:, 0] * _tilted_cosine_pdf(m["tilt"], wo) + m["weights"][:, 1] * _slope_ggx_pdf(m, wi, wo)
        return p * (wo[:, 2] > 0)

    def sample(self, latent: Tensor, wi: Tensor, u: Tensor) -> Tensor:
        """u (N, 3): u[:, 0] picks the component, u[:, 1:] samples it."""
        m = self.mixture(latent, wi)
        diffuse = _tilted_cosine_sample(m["tilt"], u[:, 1:3])
        glossy = _slope_ggx_sample(m, wi, u[:, 1:3])
        return torch.where((u[:, :1] < m["weights"][:, :1]), diffuse, glossy)


def _tilted_normal(tilt: Tensor) -> Tensor:
    n = torch.cat([-tilt, torch.ones_like(tilt[:, :1])], -1)
    return n / n.norm(dim=-1, keepdim=True)


def _tilted_cosine_pdf(tilt: Tensor, wo: Tensor) -> Tensor:
    return (wo * _tilted_normal(tilt)).sum(-1).clamp(min=0.0) / math.pi


def _tilted_cosine_sample(tilt: Tensor, u: Tensor) -> Tensor:
    r, phi = u[:, 0].sqrt(), 2.0 * math.pi * u[:, 1]
    local = torch.stack([r * phi.cos(), r * phi.sin(), (1.0 - u[:, 0]).clamp(min=0).sqrt()], -1)
    n = _tilted_normal(tilt)
    z_axis, x_axis = torch.eye(3, dtype=n.dtype, device=n.device)[[2, 0]]
    helper = torch.where(n[:, 2:3].abs() < 0.9, z_axis, x_axis)
    t = torch.nn.functional.normalize(torch.cross(helper, n, dim=-1), dim=-1)
    b = torch.cross(n, t, dim=-1)
    return local[:, :1] * t + local[:, 1:2] * b + local[:, 2:3] * n


def _slope_transform(m: dict[str, Tensor]) -> tuple[Tensor, Tensor, Tensor]:
    """(alpha_x, alpha_y, rho), each (N, 1): the stretch and shear of the slope space."""
    return m["alpha"][:, 0:1], m["alpha"][:, 1:2], m["rho"]


def _slope_ggx_pdf(m: dict[str, Tensor], wi: Tensor, wo: Tensor) -> Tensor:
    """Density of wo: slope density of h, to h in solid angle (/cos^3), to wo (/4 |wo.h|)."""
    h = wi + wo
    h = h / h.norm(dim=-1, keepdim=True).clamp(min=1e-12)
    hz = h[:, 2:3].clamp(min=1e-6)
    slope = -h[:, :2] / hz - m["offset"]
    ax, ay, rho = _slope_transform(m)
    # Standard slope s = L^-1 (slope): x' = x / ax, y' = (y / ay - rho x') / sqrt(1 - rho^2)
    sx = slope[:, 0:1] / ax
    sq = (1.0 - rho * rho).sqrt()
    sy = (slope[:, 1:2] / ay - rho * sx) / sq
    p22 = 1.0 / (math.pi * (1.0 + sx * sx + sy * sy) ** 2) / (ax * ay * sq)
    p = p22 / hz ** 3 / (4.0 * (wo * h).sum(-1, keepdim=True).abs().clamp(min=1e-6))
    return torch.where(h[:, 2:3] > 0, p, torch.zeros_like(p)).squeeze(-1)


def _slope_ggx_sample(m: dict[str, Tensor], wi: Tensor, u: Tensor) -> Tensor:
    """A standard GGX slope (radial inverse CDF), stretched, sheared, offset; wo = reflect(wi, h)."""
    r = (u[:, 0:1] / (1.0 - u[:, 0:1]).clamp(min=1e-7)).sqrt()
    phi = 2.0 * math.pi * u[:, 1:2]
    sx, sy = r * phi.cos(), r * phi.sin()
    ax, ay, rho = _slope_transform(m)
    x = ax * sx
    y = ay * (rho * sx + (1.0 - rho * rho).sqrt() * sy)
    slope = torch.cat([x, y], -1) + m["offset"]
    h = torch.cat([-slope, torch.ones_like(x)], -1)
    h = h / h.norm(dim=-1, keepdim=True)
    return 2.0 * (wi * h).sum(-1, keepdim=True) * h - wi
