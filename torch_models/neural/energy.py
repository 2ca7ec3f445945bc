"""The white furnace and the energy guard of a decoder whose latents may gain energy.

Each fitted representative is checked with a white furnace (albedo of f_neu plus
T times a white Lambertian, by a half-vector quadrature and by Monte Carlo); one
that exceeds 1 is fitted again under an albedo penalty, and what still exceeds 1
(the Monte Carlo estimate beyond 3 sigma) gets an energy scale < 1 for its f_neu,
recorded in ``neural.json``. A decoder that is bounded by construction
(``decoder.bounded``: the hybrid, with or without unit lobes, unless its unit lobes
divide by a table that reads short of a lobe's albedo, as Cycles' own does) skips
both: its fits and generated latents pass as they are, and ``furnace`` stays a
measurement.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import torch
from torch import Tensor

from richmat_addon.core.stage_clock import StageClock

from .data import cosine_hemisphere, make_batch, view_directions
from .fitting import FIT_BATCH, FIT_BUFFER, deterministic, fitting_loss, fitting_pool
from .quadrature import QUADRATURE_THETA, VIEW_COSINES, QuadratureSums, half_vector_albedo, half_vector_nodes, summed_albedo
from .weights import NeuralModel

SCALE_STEP = 1.0 / 1024  # grid of the energy scale (a power of two: exact in float32)

# The quadrature integrates a Lambertian to within 0.06 % at every view angle: a latent with
# T = 1 and no f_neu is a white diffuse surface, not an energy gain.
QUADRATURE_TOLERANCE = 2e-3
# A decoder bounded by construction puts many latents at the bound (a white dielectric's R + T = 1),
# where 64 polar rings read grazing views up to 6 % high, and 32 azimuths cut the horizon so coarsely
# at cos 0.05 that corner latents of the box read 0.3-0.6 % high (0.995 with 128 azimuths).
BOUNDED_QUADRATURE_THETA = 256
BOUNDED_QUADRATURE_PHI = 128
# What the guard writes is what renders: it holds the quadrature to 1 itself. A texel it
# left at a quadrature albedo of 1.0016 read 1.0013 +- 0.00007 by 65 k fresh samples.
GUARD_TOLERANCE = 0.0


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


def guard(model: NeuralModel, z: Tensor, seed: int = 0, rounds: int = 4) -> Tensor:
    """(K,) energy scales that hold up under fresh furnace estimates.

    One estimate can miss a narrow peak that a fresh one finds, so a repair based on
    it alone may not hold: the scaled latents (only those: the rest passed the
    deterministic quadrature and a confirmed Monte Carlo test) are measured again
    with new samples and scaled further where they still gain energy, for up to
    ``rounds`` estimates. Every round but the last repairs to the point estimates
    (``Furnace.energy_scale`` without the margin), since the next round checks the
    repair; the last keeps the margin, as nothing checks it after. The quadrature is
    held to 1 + ``GUARD_TOLERANCE``, not the looser bound a fit's check allows.
    """
    scale = torch.ones(len(z))
    if model.decoder.bounded:
        return scale
    todo = torch.arange(len(z))
    sums = half_vector_albedo(model, z)  # deterministic: a scaled latent's quadrature follows from it
    for r in range(rounds):
        check = furnace(model, z[todo], seed=seed + 7919 * r, energy_scale=scale[todo], quadrature=sums[todo],
                        tolerance=GUARD_TOLERANCE)
        if not check.failing.any():
            break
        repair = check.energy_scale(margin=r == rounds - 1)
        scale[todo] = torch.floor(scale[todo] * repair / SCALE_STEP) * SCALE_STEP
        todo = todo[check.failing]
    return scale


REFIT_STEPS = 150
REFIT_LATENTS = 512  # latents penalised per refit step: a textured material can have thousands failing
REFIT_GRID = (32, 8)  # coarse half-vector quadrature for the penalty (1280 evaluations per latent and step)
REFIT_TARGET = 0.995  # the coarse grid's albedo is held below this, a margin for its error against the furnace's
REFIT_LR = 3e-3


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


def fit_bounded(model: NeuralModel, vectors: np.ndarray, z: Tensor, seed: int = 0,
                steps: int = REFIT_STEPS) -> BoundedFit:
    """Check fitted latents (K, 6) of ``vectors`` in the white furnace and fit the failing
    ones again with the fitting loss plus a penalty on albedo above 1.

    The reference itself can sit at or above 1: a white-based dielectric's layering
    gives exactly 1 (T = 1 - R) at every angle, and Cycles' tabulated albedo of a
    near-smooth coat reads ~5 % low at cos 0.05, so its layering gains that much
    (docs/neural-material.md). A faithful fit lands on either side of 1; the refit
    moves it to the side the furnace accepts, at the least cost in the loss. What
    still gains energy is then scaled by ``Furnace.energy_scale``.
    """
    clock = StageClock()
    if model.decoder.bounded:
        with clock.stage("check"):
            check = bound_furnace(model, z)
        return BoundedFit(z, check, torch.zeros(len(z), dtype=torch.bool), clock.record(whole_process=False))
    with clock.stage("check"):
        check = furnace(model, z, seed=seed)
    refitted = check.failing.clone()
    failing = refitted.nonzero(as_tuple=True)[0]
    if len(failing) and steps > 0:
        z = z.clone()
        with clock.stage("refit"):
            z[failing] = _refit(model, vectors[failing.numpy()], z[failing], steps, seed)
        with clock.stage("recheck"):
            again = furnace(model, z[failing], seed=seed + 1)
        for name in ("albedos", "std_errors", "transmissions", "quadrature"):
            getattr(check, name)[failing] = getattr(again, name)
    return BoundedFit(z, check, refitted, clock.record(whole_process=False))


def _refit(model: NeuralModel, vectors: np.ndarray, z0: Tensor, steps: int, seed: int) -> Tensor:
    """``steps`` Adam steps on the fitting loss plus the summed albedo excess over ``REFIT_TARGET``
    at ``VIEW_COSINES`` (a coarse half-vector quadrature) of up to ``REFIT_LATENTS`` latents."""
    pool = fitting_pool(model, vectors)
    gen = torch.Generator().manual_seed(seed + 104_729)
    buffer = [make_batch(pool, FIT_BATCH, gen) for _ in range(min(steps, FIT_BUFFER))]
    nodes = [half_vector_nodes(mu, *REFIT_GRID) for mu in VIEW_COSINES]
    z = z0.clone().requires_grad_(True)
    opt = torch.optim.Adam([z], lr=REFIT_LR)
    with deterministic():
        for step in range(steps):
            b = buffer[step % len(buffer)]
            pick = torch.randperm(len(z), generator=gen)[:REFIT_LATENTS]
            excess = sum(torch.relu(summed_albedo(model, z[pick], wi, wo, w).albedo() - REFIT_TARGET)
                         for wi, wo, w in nodes)
            loss = fitting_loss(model, z[b.index], b) + excess.mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
    return z.detach()


def bound_furnace(model: NeuralModel, z: Tensor) -> Furnace:
    """The furnace of a decoder bounded by construction, read off its head's slot weights: at each
    of ``VIEW_COSINES`` the albedo is at most the weight of every slot but the absorbed one, and T
    is the transmitted slot's. Exact bounds, no samples (standard errors 0)."""
    dec = model.decoder
    rows, ts = [], []
    with torch.no_grad():
        for mu in VIEW_COSINES:
            weights = dec.head_at(z, view_directions(torch.full((len(z), 1), mu))).weights
            rows.append(weights[:, :-1].sum(-1))
            ts.append(weights[:, dec.t_slot])
    bound = torch.stack(rows, 1).clamp(max=1.0)  # < 1 exactly; a float32 softmax sums to 1 +- rounding
    return Furnace(bound, torch.zeros_like(bound), torch.stack(ts, 1), bound.clone())


def furnace(model: NeuralModel, z: Tensor, n: int = 1024, seed: int = 0,
            energy_scale: Tensor | None = None, confirm: int = 16,
            quadrature: QuadratureSums | None = None, tolerance: float = QUADRATURE_TOLERANCE) -> Furnace:
    """White furnace of s f_neu + T * (white Lambertian) at ``VIEW_COSINES``.

    s is ``energy_scale`` per latent (1 when None), to re-check repaired latents.
    Two estimates, because each misses what the other sees:
    - a deterministic quadrature over half vectors (``half_vector_albedo``), dense
      around the mirror direction, where narrow lobes sit: Monte Carlo estimates of a
      lobe narrower than the sampling decoder's are heavy-tailed and usually read
      far too low (an albedo of 2.6 read as 0.24 +- 0.02);
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
