"""The MLP's energy repair: its latents may gain energy, so fits and generated latents are fixed.

A fitted representative that fails the white furnace (``furnace``) is fitted again
under an albedo penalty; what still exceeds 1 (the Monte Carlo estimate beyond 3 sigma)
gets an energy scale < 1 for its f_neu, recorded in ``neural.json``. Generated latents,
which no fit can move, get the scale from ``guard``.
"""
from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from ...stage_clock import StageClock
from ..data import make_batch
from ..fit.latents import FIT_BATCH, FIT_BUFFER, deterministic, fitting_loss, fitting_pool
from ..furnace import SCALE_STEP, BoundedFit, furnace
from ..model import NeuralModel
from ..quadrature import VIEW_COSINES, half_vector_albedo, half_vector_nodes, summed_albedo

# What the guard writes is what renders: it holds the quadrature to 1 itself, with no allowance
# (docs/neural-material.md, "White furnace and repair").
GUARD_TOLERANCE = 0.0


def guard(model: NeuralModel, z: Tensor, seed: int, rounds: int = 4) -> Tensor:
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


def fit_bounded(model: NeuralModel, vectors: np.ndarray, z: Tensor, seed: int, steps: int) -> BoundedFit:
    """Check fitted latents (K, 6) of ``vectors`` in the white furnace and fit the failing
    ones again (``steps`` Adam steps) with the fitting loss plus a penalty on albedo above 1.

    The reference itself can sit at or above 1: a white-based dielectric's layering
    gives exactly 1 (T = 1 - R) at every angle, and Cycles' tabulated albedo of a
    near-smooth coat reads low at grazing views, so its layering gains energy there
    (docs/neural-material.md). A faithful fit lands on either side of 1; the refit
    moves it to the side the furnace accepts, at the least cost in the loss. What
    still gains energy is then scaled by ``Furnace.energy_scale``.
    """
    clock = StageClock()
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
