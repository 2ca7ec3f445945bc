"""Fit an enhanced material's latent textures against the frozen decoder (paper sec. 4.3).

Model no more than the material needs: texels with equal parameter vectors are
fitted once (exact dedupe), then vectors that agree to within a quantisation
step in the normalised parameter space are merged (every texel is within half a
step, ``QUANT / 2`` per normalised coordinate, of its representative). Latents
start from the encoder and are optimised with the training loss on samples of
the analytic model; they are scattered back to texels as two RGB EXR textures.
A constant material stays one vector in ``neural.json``.

Energy: each fitted representative is checked with a white furnace (albedo of
f_neu plus T times a white Lambertian, by a half-vector quadrature and by Monte
Carlo); one that exceeds 1 (the Monte Carlo estimate beyond 3 sigma) gets an
energy scale < 1 for its f_neu, recorded in ``neural.json``.
"""
from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from richmat_addon.core.schema import CHANNEL_SLICES, PARAMS
from .data import Batch, angular_floor, cosine_hemisphere, make_batch, view_directions
from .networks import normalise_params
from .train import decoder_loss
from .weights import NeuralModel

QUANT = 1.0 / 256.0
FIT_BATCH = 16384  # (texel, wi, wo) samples per Adam step, shared by all vectors fitted together
FIT_BUFFER = 24  # batches of analytic targets drawn per fit, then reused


@dataclass
class MaterialVectors:
    """Per-texel parameter vectors of a material folder, deduplicated."""

    shape: tuple[int, int] | None  # texture size, or None for a constant material
    unique: np.ndarray  # (K, 22) representatives
    inverse: np.ndarray  # (H*W,) representative of every texel (empty when constant)
    exact_unique: int  # distinct vectors before merging

    def texels(self, per_vector: Tensor) -> np.ndarray:
        """Per-representative values (K, C) scattered to the texture, (H, W, C)."""
        assert self.shape is not None, "a constant material has no texels"
        values = per_vector.reshape(len(per_vector), -1)[torch.from_numpy(self.inverse)]
        return np.ascontiguousarray(values.reshape(*self.shape, -1).numpy())


def read_exr(path: Path) -> np.ndarray:
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(str(path))
    if buf.has_error:
        raise ValueError(f"{path}: cannot read ({buf.geterror().strip()})")
    return np.asarray(buf.get_pixels(oiio.FLOAT), np.float32)


def read_vectors(folder: Path) -> MaterialVectors:
    """Parameter vectors of a folder written by ``enhance`` (params.json + EXRs)."""
    record_path = folder / "params.json"
    if not record_path.is_file():
        raise ValueError(f"{folder}: not an enhanced material folder (no params.json)")
    record = json.loads(record_path.read_text())
    maps = {name: read_exr(folder / file) for name, file in record.get("textures", {}).items()
            if name in CHANNEL_SLICES}
    shape = max((m.shape[:2] for m in maps.values()), default=None, key=lambda s: s[0] * s[1])
    columns = []
    for p in PARAMS:
        if p.name in maps:
            m = maps[p.name]
            if m.shape[:2] != shape:  # nearest resampling to the largest map
                rows = (np.arange(shape[0]) * m.shape[0] // shape[0])[:, None]
                cols = (np.arange(shape[1]) * m.shape[1] // shape[1])[None, :]
                m = m[rows, cols]
            columns.append(m.reshape(-1, p.channels))
        else:
            value = np.atleast_1d(np.asarray(record["constants"][p.name], np.float32))
            columns.append(np.broadcast_to(value, ((shape[0] * shape[1]) if shape else 1, p.channels)))
    vectors = np.nan_to_num(np.concatenate(columns, 1).astype(np.float32))
    exact, inverse = np.unique(vectors, axis=0, return_inverse=True)
    keys = np.round(normalise_params(torch.from_numpy(exact)).numpy() / QUANT).astype(np.int64)
    merged_keys, merged_of_exact = np.unique(keys, axis=0, return_inverse=True)
    representatives = np.zeros((len(merged_keys), vectors.shape[1]), np.float32)
    np.add.at(representatives, merged_of_exact.ravel(), exact)
    representatives /= np.bincount(merged_of_exact.ravel())[:, None]
    texel_rep = merged_of_exact.ravel()[inverse.ravel()] if shape else np.zeros(0, np.int64)
    return MaterialVectors(shape, representatives, texel_rep, len(exact))


def fitting_pool(model: NeuralModel, vectors: np.ndarray) -> Tensor:
    """(K, 22) vectors as ``model`` was trained to draw them (its angular floor applied)."""
    return angular_floor(vectors, model.alpha_floor)


def fitting_loss(model: NeuralModel, z: Tensor, batch: Batch) -> Tensor:
    """The loss ``model`` was trained with (its relative term included), which fitting minimises."""
    return decoder_loss(model.decoder, z, batch, relative_weight=model.relative_weight)


def fit_latents(model: NeuralModel, vectors: np.ndarray, steps: int, batch: int = FIT_BATCH, seed: int = 0,
                start: Tensor | None = None, progress=None,  # type: ignore[no-untyped-def]
                penalty: Callable[[int, Tensor], Tensor] | None = None) -> Tensor:
    """Latents (K, 6) of K parameter vectors, from the encoder (or ``start``), optimised ``steps`` times.

    Analytic targets cost far more than a decoder step, so ``FIT_BUFFER`` batches
    are drawn once and cycled through (fewer when there are fewer steps).
    ``penalty(step, z)`` is added to the loss: a way to try other objectives
    (bench/fit_limits.py) without a second optimisation loop.
    """
    pool = fitting_pool(model, vectors)
    with torch.no_grad():
        z0 = model.encoder(pool) if start is None else start
    z = z0.clone().requires_grad_(True)
    opt = torch.optim.Adam([z], lr=1e-2)
    gen = torch.Generator().manual_seed(seed)
    buffer = [make_batch(pool, batch, gen) for _ in range(min(steps, FIT_BUFFER))]
    with deterministic():
        for step in range(steps):
            b = buffer[step % len(buffer)]
            loss = fitting_loss(model, z[b.index], b)
            if penalty is not None:
                loss = loss + penalty(step, z)
            opt.zero_grad()
            loss.backward()
            opt.step()
            if progress is not None:
                progress(step, loss.item(), z.detach())
    return z.detach()


@contextmanager
def deterministic() -> Iterator[None]:
    """Torch's deterministic kernels while fitting.

    The gradient of ``z[index]`` scatters into the latent rows; with more than one
    thread the default CPU kernel sums in a varying order, so two runs (a farm job
    and its restart) would write latents a half-float step apart.
    """
    before = torch.are_deterministic_algorithms_enabled()
    torch.use_deterministic_algorithms(True)
    try:
        yield
    finally:
        torch.use_deterministic_algorithms(before)


VIEW_COSINES = (1.0, 0.7, 0.4, 0.15, 0.05)
SCALE_STEP = 1.0 / 1024  # grid of the energy scale (a power of two: exact in float32)


QUADRATURE_THETA = 64  # half-vector polar rings
QUADRATURE_PHI = 32  # azimuths per ring: a lobe around the mirror direction sits at h = n for every wi,
# where rings are tiny, so polar resolution buys accuracy and azimuths mostly cost (10 k evaluations per latent)
# The quadrature integrates a Lambertian to within 0.06 % at every view angle: a latent with
# T = 1 and no f_neu is a white diffuse surface, not an energy gain.
QUADRATURE_TOLERANCE = 2e-3
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
    check = furnace(model, z, seed=seed)
    refitted = check.failing.clone()
    failing = refitted.nonzero(as_tuple=True)[0]
    if len(failing) and steps > 0:
        z = z.clone()
        z[failing] = _refit(model, vectors[failing.numpy()], z[failing], steps, seed)
        again = furnace(model, z[failing], seed=seed + 1)
        for name in ("albedos", "std_errors", "transmissions", "quadrature"):
            getattr(check, name)[failing] = getattr(again, name)
    return BoundedFit(z, check, refitted)


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
            excess = sum(torch.relu(_summed_albedo(model, z[pick], wi, wo, w).albedo() - REFIT_TARGET)
                         for wi, wo, w in nodes)
            loss = fitting_loss(model, z[b.index], b) + excess.mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
    return z.detach()


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
    sums = half_vector_albedo(model, z) if quadrature is None else quadrature
    return Furnace(albedos, std_errors, sums.diffuse, sums.albedo(scale), tolerance)


def _significant_gain(albedos: Tensor, std_errors: Tensor) -> Tensor:
    """Monte Carlo albedos above 1 by more than 3 standard errors."""
    return albedos > 1.0 + 3.0 * std_errors


def half_vector_grid(n_theta: int = QUADRATURE_THETA, n_phi: int = QUADRATURE_PHI) -> tuple[Tensor, Tensor]:
    """Midpoint quadrature nodes h (M, 3) on the upper hemisphere and their solid angles (M,).

    Polar angle theta_h = (pi / 2) t^3 for uniform t: rings crowd around the normal,
    where a narrow lobe's half vectors are (the innermost rings resolve alpha ~ 1e-3)."""
    t = (torch.arange(n_theta, dtype=torch.float64) + 0.5) / n_theta
    theta = 0.5 * math.pi * t ** 3
    d_theta = 1.5 * math.pi * t ** 2 / n_theta
    phi = (torch.arange(n_phi, dtype=torch.float64) + 0.5) * 2 * math.pi / n_phi
    th, ph = torch.meshgrid(theta, phi, indexing="ij")
    h = torch.stack([th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()], -1).reshape(-1, 3)
    d_omega = (th.sin() * d_theta[:, None] * (2 * math.pi / n_phi)).reshape(-1)
    return h.float(), d_omega.float()


def half_vector_nodes(mu: float, n_theta: int = QUADRATURE_THETA,
                      n_phi: int = QUADRATURE_PHI) -> tuple[Tensor, Tensor, Tensor]:
    """wi (3,) at view cosine ``mu``, outgoing directions wo (M, 3) and weights (M,) such that
    sum(weights * g(wi, wo)) integrates g over the outgoing hemisphere.

    wo = reflect(wi, h) maps the half-vector hemisphere onto all outgoing directions
    with d omega_o = 4 (wi . h) d omega_h; those below the horizon get weight 0."""
    h, d_omega = half_vector_grid(n_theta, n_phi)
    wi = view_directions(torch.tensor([[mu]]))[0]
    cos_h = h @ wi
    wo = 2 * cos_h[:, None] * h - wi
    weight = torch.where((cos_h > 0) & (wo[:, 2] > 0), 4 * cos_h * d_omega, torch.zeros_like(cos_h))
    return wi, wo, weight


@dataclass
class QuadratureSums:
    """The half-vector quadrature of K latents (at ``VIEW_COSINES``, or one view): f_neu's albedo
    per colour channel, unscaled, (K, [A,] 3), and the diffuse base's T / pi, (K, [A])."""

    reflected: Tensor
    diffuse: Tensor

    def albedo(self, scale: Tensor | None = None) -> Tensor:
        """The brightest channel's albedo of s f_neu + T / pi (s = 1 when None): linear in s,
        so a repaired latent needs no second quadrature."""
        reflected = self.reflected
        if scale is not None:
            reflected = reflected * scale.reshape((-1,) + (1,) * (reflected.dim() - 1))
        return (reflected + self.diffuse[..., None]).amax(-1)

    def __getitem__(self, index: Tensor) -> QuadratureSums:
        return QuadratureSums(self.reflected[index], self.diffuse[index])


def half_vector_albedo(model: NeuralModel, z: Tensor, n_theta: int = QUADRATURE_THETA,
                       chunk: int = 1 << 18) -> QuadratureSums:
    """By quadrature at ``VIEW_COSINES``: f_neu's albedo per channel and the diffuse base's.

    T comes out of the same network as f, so it varies a little with wo, as the
    renderer evaluates it: the diffuse base is integrated too, not taken at one wo."""
    reflected, diffuse = torch.zeros(len(z), len(VIEW_COSINES), 3), torch.zeros(len(z), len(VIEW_COSINES))
    with torch.no_grad():
        for a, mu in enumerate(VIEW_COSINES):
            wi, wo, weight = half_vector_nodes(mu, n_theta)
            per_chunk = max(1, chunk // len(wo))
            for k0 in range(0, len(z), per_chunk):
                k = slice(k0, k0 + per_chunk)
                sums = _summed_albedo(model, z[k], wi, wo, weight)
                reflected[k, a], diffuse[k, a] = sums.reflected, sums.diffuse
    return QuadratureSums(reflected, diffuse)


def _summed_albedo(model: NeuralModel, z: Tensor, wi: Tensor, wo: Tensor, weight: Tensor) -> QuadratureSums:
    """At one wi, the weighted sums over the outgoing nodes wo (M, 3): f_neu's albedo (K, 3)
    and the diffuse base's (K,)."""
    k, m = len(z), len(wo)
    f, t, _ = model.decoder(z.repeat_interleave(m, 0), wi.expand(k * m, 3), wo.repeat(k, 1))
    reflected = (f.reshape(k, m, 3) * weight[None, :, None]).sum(1)
    diffuse = (t.reshape(k, m) * wo[:, 2] * weight).sum(1) / math.pi
    return QuadratureSums(reflected, diffuse)


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
