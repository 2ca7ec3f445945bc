"""The white furnace: does a decoder's latent reflect more light than it receives?

The albedo of f_neu plus T times a white Lambertian, per latent and view angle, by a
half-vector quadrature and by Monte Carlo (each misses what the other sees). Every kind
is measured with it (``validity``); what a kind does about latents that fail is its own
(``energy``). ``BoundedFit`` is what every kind's fit check returns.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import torch
from torch import Tensor

from .data import cosine_hemisphere, view_directions
from .model import NeuralModel
from .quadrature import VIEW_COSINES, QuadratureSums, half_vector_albedo

SCALE_STEP = 1.0 / 1024  # grid of the energy scale (a power of two: exact in float32)

# The quadrature's own error on a white Lambertian (docs/neural-material.md): a latent with
# T = 1 and no f_neu is a white diffuse surface, not an energy gain.
QUADRATURE_TOLERANCE = 2e-3
# A decoder bounded by construction puts many latents at the bound (a white dielectric's R + T = 1),
# where the default grid reads grazing views high and cuts the horizon at cos 0.05 coarsely enough
# to flag corner latents of the box: it is measured on a finer grid.
BOUNDED_QUADRATURE_THETA = 256
BOUNDED_QUADRATURE_PHI = 128


@dataclass
class Furnace:
    """Per latent and view angle (K, A): albedo of the brightest channel by Monte Carlo, its
    standard error, the diffuse base's share (T's albedo), and the albedo by half-vector quadrature.
    ``tolerance`` is how far the quadrature may exceed 1 before an angle counts as gaining energy."""

    albedos: Tensor
    std_errors: Tensor
    transmissions: Tensor
    quadrature: Tensor
    tolerance: float = QUADRATURE_TOLERANCE

    @property
    def albedo(self) -> Tensor:
        """(K,) the worst albedo over the view angles and the two estimates."""
        return torch.maximum(self.albedos, self.quadrature).max(1).values

    def _over(self) -> Tensor:
        """(K, A) angles that gain energy: by quadrature, or by Monte Carlo beyond 3 standard errors."""
        return (self.quadrature > 1.0 + self.tolerance) | _significant_gain(self.albedos, self.std_errors)

    @property
    def failing(self) -> Tensor:
        """(K,) some view angle gains energy."""
        return self._over().any(1)

    def energy_scale(self, margin: bool = True) -> Tensor:
        """f_neu scale per latent that brings every failing angle's albedo to 1 at most, keeping T.

        At an angle, s F + T <= 1 needs s <= (1 - T) / F with F = albedo - T. F is
        the larger of the quadrature and the Monte Carlo upper 3-sigma bound, so a
        fresh estimate of the repaired albedo stays below 1 too; the smallest bound
        over the failing angles wins (1 where none fails). Rounded down to a
        multiple of ``SCALE_STEP``: float noise in the estimate (thread scheduling,
        batch shapes) then leaves the written scale map bit-identical across runs,
        and rounding down keeps it safe.

        ``margin`` False drops the Monte Carlo error bar: F is the quadrature where
        only it gains energy, else the larger of the two point estimates. A lobe at
        the bound (a white dielectric's layering gives exactly 1) then loses the few
        tenths of a per cent it is over, not the several per cent of an error bar.
        Such a repair must be checked again with a fresh estimate, as ``guard`` does.
        """
        if margin:
            upper = torch.maximum(self.albedos + 3.0 * self.std_errors, self.quadrature)
        else:
            upper = torch.where(_significant_gain(self.albedos, self.std_errors),
                                torch.maximum(self.albedos, self.quadrature), self.quadrature)
        upper = upper - self.transmissions
        bound = (1.0 - self.transmissions) / upper.clamp(min=1e-6)
        bound = torch.where(self._over(), bound.clamp(0.0, 1.0), torch.ones_like(bound))
        return torch.floor(bound.min(1).values / SCALE_STEP) * SCALE_STEP


@dataclass
class BoundedFit:
    """Fitted latents after the energy refit, their furnace check, and which were refitted."""

    z: Tensor
    check: Furnace
    refitted: Tensor  # (K,) bool: the first fit gained energy; the latent was fitted again under the bound
    # wall ("timings_s") and CPU ("cpu_s") seconds of the check, the refit and the recheck: what the farm pays
    seconds: dict[str, dict[str, float]] = field(default_factory=dict)

    def counts(self) -> dict[str, int]:
        """How each latent came to pass: as fitted, after the refit, or by the energy scale."""
        scaled = int(self.check.failing.sum())
        return {"checked": len(self.z), "passed_as_fitted": int((~self.refitted).sum()),
                "passed_after_refit": int(self.refitted.sum()) - scaled, "repaired_by_scaling": scaled}


def furnace(model: NeuralModel, z: Tensor, n: int = 1024, seed: int = 0,
            energy_scale: Tensor | None = None, confirm: int = 16,
            quadrature: QuadratureSums | None = None, tolerance: float = QUADRATURE_TOLERANCE) -> Furnace:
    """White furnace of s f_neu + T * (white Lambertian) at ``VIEW_COSINES``.

    s is ``energy_scale`` per latent (1 when None), to re-check repaired latents.
    Two estimates, because each misses what the other sees:
    - a deterministic quadrature over half vectors (``half_vector_albedo``), dense
      around the mirror direction, where narrow lobes sit: Monte Carlo estimates of a
      lobe narrower than the sampling decoder's are heavy-tailed and usually read
      far too low;
    - Monte Carlo from a cosine + sampling-decoder mixture, for structure away from
      the mirror direction that the quadrature's coarser outer rings could miss.
      Thousands of 3-sigma tests flag some latents by chance, so every latent that
      fails with n samples is measured again with ``confirm`` * n fresh ones, and
      that estimate stands.
    ``quadrature`` passes the latents' ``half_vector_albedo`` when it is already known;
    ``tolerance`` is the quadrature's allowance over 1 (``Furnace.tolerance``).
    """
    scale = torch.ones(len(z)) if energy_scale is None else energy_scale
    albedos, std_errors = _furnace_pass(model, z, n, seed, scale)
    flagged = _significant_gain(albedos, std_errors)
    again = flagged.any(1).nonzero(as_tuple=True)[0]
    if confirm > 1 and len(again):
        angles = flagged[again]  # only the view angles that gained: the others passed their test
        a2, s2 = _furnace_pass(model, z[again], confirm * n, seed + 1, scale[again], angles)
        albedos[again] = torch.where(angles, a2, albedos[again])
        std_errors[again] = torch.where(angles, s2, std_errors[again])
    if quadrature is None:
        sums = (half_vector_albedo(model, z, BOUNDED_QUADRATURE_THETA, BOUNDED_QUADRATURE_PHI) if model.decoder.bounded
                else half_vector_albedo(model, z))
    else:
        sums = quadrature
    return Furnace(albedos, std_errors, sums.diffuse, sums.albedo(scale), tolerance)


def _significant_gain(albedos: Tensor, std_errors: Tensor) -> Tensor:
    """Monte Carlo albedos above 1 by more than 3 standard errors."""
    return albedos > 1.0 + 3.0 * std_errors


def _furnace_pass(model: NeuralModel, z: Tensor, n: int, seed: int, scale: Tensor,
                  angles: Tensor | None = None, chunk: int = 1 << 18) -> tuple[Tensor, Tensor]:
    """One Monte Carlo furnace estimate, (K, A) albedos of the brightest channel and their
    standard errors: n wo per latent and view angle from an equal mixture of the cosine
    lobe and the latent's own sampling decoder, weighted by the mixture pdf. With
    ``angles`` (K, A) bool, only those (latent, view angle) pairs are estimated (the
    rest are left 0).

    Cosine samples alone rarely land in a narrow peak, so an estimate could miss it,
    pass, and a fresh one find it: the mixture follows the peak, and the cosine half
    bounds f / pdf where the sampling decoder is thin."""
    gen = torch.Generator().manual_seed(seed)
    albedos, std_errors = torch.zeros(2, len(z), len(VIEW_COSINES))
    per_chunk = max(1, chunk // n)
    with torch.no_grad():
        for a, mu in enumerate(VIEW_COSINES):
            wi = view_directions(torch.tensor([[mu]]))
            rows = torch.arange(len(z)) if angles is None else angles[:, a].nonzero(as_tuple=True)[0]
            for k0 in range(0, len(rows), per_chunk):
                idx = rows[k0:k0 + per_chunk]
                zk = z[idx].repeat_interleave(n, 0)
                m = len(idx)
                wi_k = wi.expand(m * n, 3)
                pick = torch.rand(m * n, 1, generator=gen) < 0.5
                wo = torch.where(pick, cosine_hemisphere(m * n, gen),
                                 model.sampler.sample(zk, wi_k, torch.rand(m * n, 3, generator=gen)))
                cos_o = wo[:, 2:3].clamp(min=0.0)
                pdf = 0.5 * cos_o[:, 0] / math.pi + 0.5 * model.sampler.pdf(zk, wi_k, wo)
                f, t, _ = model.decoder(zk, wi_k, wo)
                # f and cos_o are 0 below the horizon, the only place the mixture's pdf can be 0
                value = f * scale[idx].repeat_interleave(n, 0)[:, None] + t * cos_o / math.pi
                est = (value / pdf.clamp(min=1e-12)[:, None]).reshape(m, n, 3)
                channel = est.mean(1).argmax(1)  # the brightest channel must stay <= 1
                est = est.gather(2, channel[:, None, None].expand(m, n, 1))[..., 0]
                albedos[idx, a] = est.mean(1)
                std_errors[idx, a] = est.std(1) / math.sqrt(n)
    return albedos, std_errors
