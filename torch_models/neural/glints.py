"""Microscale glints (paper sec. 5.4): f_neu times a per-point, per-wavelength noise.

The neural material leaves the diffuse base out of f_neu, so a fine-scale
effect that belongs to specular reflection can be added at render time by
modulating f_neu alone: f_neu^(i)(lambda, wi, wo) = f_neu(wi, wo) N^(i)(lambda, wi, wo).

N is built from 3D simplex noise (Perlin 2001; written from Gustavson's
"Simplex noise demystified", 2005), read at the shading point's position
(scaled by ``scale``) shifted by the half vector (``angular``), so that the
sparkle pattern moves as the view or the light moves, as a glint does. A
wave-optics pattern scales with wavelength, so each RGB channel reads the
noise at coordinates scaled by 550 nm / lambda_c, plus an offset per channel:
the three channels sparkle at different places (coloured glints).

Sparkle, not ripple: the noise n in [-1, 1] becomes max(n, 0)^sharpness /
E[max(n, 0)^sharpness], whose mean is 1 (E is measured once per pattern, with
many points); ``strength`` blends it with 1:

    N = (1 - strength) + strength * sparkle,   in [1 - strength, 1 - strength + strength / E].

The mean of N over the surface is 1: glints redistribute f_neu's energy over
the surface and keep its average (and so the furnace check) unchanged.
"""
from __future__ import annotations

import torch
from torch import Tensor

WAVELENGTHS_NM = (610.0, 550.0, 465.0)  # R, G, B
_SKEW, _UNSKEW = 1.0 / 3.0, 1.0 / 6.0
# The 12 gradients: midpoints of the edges of a cube (Perlin's "improved" set).
_GRADIENTS = torch.tensor([[1, 1, 0], [-1, 1, 0], [1, -1, 0], [-1, -1, 0], [1, 0, 1], [-1, 0, 1],
                           [1, 0, -1], [-1, 0, -1], [0, 1, 1], [0, -1, 1], [0, 1, -1], [0, -1, -1]],
                          dtype=torch.float32)
# Kernel (r2 - |d|^2)^4: with r2 = 0.5 the kernel ends inside the simplices that
# share the corner, so the sum is continuous (Gustavson's 0.6 leaves small seams).
_R2 = 0.5
_PEAK = 74.0  # the largest |sum| measured over 1M points is 0.0130: this maps the noise into [-1, 1]


class SimplexNoise3:
    """3D simplex noise in [-1, 1], one permutation table per seed (deterministic)."""

    def __init__(self, seed: int = 0) -> None:
        self.perm = torch.randperm(256, generator=torch.Generator().manual_seed(seed))

    def _gradient(self, cell: Tensor) -> Tensor:
        """A pseudo-random gradient per integer lattice point (N, 3), by nested permutation."""
        h = self.perm[cell[:, 2] & 255]
        h = self.perm[(cell[:, 1] + h) & 255]
        h = self.perm[(cell[:, 0] + h) & 255]
        return _GRADIENTS[h % 12]

    def __call__(self, p: Tensor) -> Tensor:
        """Noise at points p (N, 3), (N,)."""
        p = p.float()
        # Skew: the simplex grid becomes a cube grid; find the cube and the corner offsets.
        cell = torch.floor(p + p.sum(-1, keepdim=True) * _SKEW)
        d0 = p - (cell - cell.sum(-1, keepdim=True) * _UNSKEW)
        # The simplex inside the cube: walk the axes from the largest offset to the
        # smallest (ties broken x, y, z so that exactly one order is chosen).
        x, y, z = d0.unbind(-1)
        rank = torch.stack([(x >= y).int() + (x >= z).int(), (y > x).int() + (y >= z).int(),
                            (z > x).int() + (z > y).int()], -1)
        cell = cell.long()
        total = torch.zeros(len(p))
        for k, step in enumerate((torch.zeros_like(rank), (rank == 2).long(), (rank >= 1).long(),
                                  torch.ones_like(rank))):
            d = d0 - step + k * _UNSKEW
            falloff = (_R2 - (d * d).sum(-1)).clamp(min=0.0)
            total = total + falloff ** 4 * (self._gradient(cell + step) * d).sum(-1)
        return (_PEAK * total).clamp(-1.0, 1.0)


class GlintPattern:
    """Glint multiplier of f_neu: (N, 3), mean 1, per RGB channel.

    ``scale``: noise cells per unit length (sparkle size ~ 1 / scale);
    ``strength`` in [0, 1]: 0 leaves f_neu unchanged; ``sharpness``: how sparse
    the sparkles are; ``angular``: noise cells the pattern moves per unit change of
    the half vector. Kept near 1: under an environment light a pixel gathers the
    half vectors of the whole lobe, and a pattern that moves much faster averages
    away into plain haze.
    """

    def __init__(self, scale: float = 20.0, strength: float = 0.7, seed: int = 0,
                 sharpness: float = 6.0, angular: float = 1.0) -> None:
        if not 0.0 <= strength <= 1.0:
            raise ValueError(f"glint strength must be in [0, 1], got {strength}")
        self.scale, self.strength, self.sharpness, self.angular = scale, strength, sharpness, angular
        self.noise = SimplexNoise3(seed)
        gen = torch.Generator().manual_seed(seed)
        self.offsets = 1000.0 * torch.rand(3, 3, generator=gen)  # per channel
        self.frequency = torch.tensor([550.0 / lam for lam in WAVELENGTHS_NM])
        # E[max(n, 0)^sharpness], measured on many points spread far over the noise.
        probe = 1000.0 * torch.rand(1 << 16, 3, generator=gen)
        self.normaliser = float(self._sparkle(probe).mean())

    @property
    def range(self) -> tuple[float, float]:
        """Bounds of the multiplier."""
        return 1.0 - self.strength, 1.0 - self.strength + self.strength / self.normaliser

    def _sparkle(self, q: Tensor) -> Tensor:
        return self.noise(q).clamp(min=0.0) ** self.sharpness

    def __call__(self, positions: Tensor, wi: Tensor | None = None, wo: Tensor | None = None) -> Tensor:
        """Multiplier (N, 3) at positions (N, 3); with local wi, wo the pattern follows the half vector."""
        q = self.scale * positions.float()
        if wi is not None and wo is not None and self.angular:
            h = wi + wo
            q = q + self.angular * h / h.norm(dim=-1, keepdim=True).clamp(min=1e-12)
        channels = [self._sparkle(q * self.frequency[c] + self.offsets[c]) for c in range(3)]
        return (1.0 - self.strength) + self.strength / self.normaliser * torch.stack(channels, -1)

    def at(self, positions: Tensor) -> "Glints":
        """The pattern bound to shading points: what ``NeuralBsdf(glints=...)`` takes."""
        return Glints(self, positions)


class Glints:
    """A glint pattern at fixed shading points; called with the local (wi, wo) of those points."""

    def __init__(self, pattern: GlintPattern, positions: Tensor) -> None:
        self.pattern, self.positions = pattern, positions

    def __call__(self, wi: Tensor, wo: Tensor) -> Tensor:
        return self.pattern(self.positions, wi, wo)
