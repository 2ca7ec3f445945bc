"""A bounded set of representatives for a material with more distinct vectors than a fit can afford.

Photo-scanned textures hold a distinct parameter vector in most of their texels, so a fit
whose cost is linear in the distinct vectors grows with the texture. Above a budget the
fit instead fits that many representatives and gives every texel its representative's
latent: a coarser dedupe, chosen for the appearance error it causes.

- **Metric.** Distance in the encoder's latent space (``encoder``): the encoder was trained
  so that its latent decodes to the vector's BRDF, so it weighs each parameter by how much it
  moves what the decoder draws, non-linearly (a metal against a dielectric of the same colour
  is far apart however close their numbers). Measured against it (bench/neural/fit_bounded.py):
  the normalised parameters (``plain``) and the normalised parameters weighed by the RMS change
  of log(1 + reflected light) per unit of each (``appearance``, the fit error's measure
  linearised over the material).
- **Representatives.** Weighted k-means (Lloyd), each vector weighed by the texels it stands
  for, on a grid pre-merge of at most ``PREMERGE`` x budget cells so that choosing them does not
  grow with the texture either; a representative is the texel-weighted mean of its members.
- **Transfer.** Each vector takes its representative's fitted latent (``nearest``); the bench
  measures the alternative of adding the encoder's difference between the two (``residual``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import torch
from torch import Tensor

from richmat_addon.core.schema import bounds
from richmat_addon.core.texel_vectors import TexelVectors, normalise, unique_rows
from torch_models.brdf.model import LayeredBsdf, params_from_vectors

from ..data import make_batch
from ..model import NeuralModel
from .latents import fitting_pool

METRICS = ("encoder", "appearance", "plain")
TRANSFERS = ("nearest", "residual")
PREMERGE = 8  # k-means runs on at most this many grid cells per representative
LLOYD_ITERATIONS = 8
METRIC_VECTORS, METRIC_DIRECTIONS = 256, 64  # the sample the metric's weights are measured on
METRIC_DELTA = 1.0 / 32.0  # the finite difference, in normalised parameter units
GREY_BASE = 0.5  # the diffuse base's colour in the measure, as in ``error.py``
CHUNK = 1 << 12  # points per distance block (a block of distances stays in cache)


@dataclass
class Representatives:
    """``budget`` representatives of K vectors: their parameter vectors and each vector's own."""

    vectors: np.ndarray  # (B, 22) the representatives (count-weighted centroids)
    of_vector: np.ndarray  # (K,) the representative of each vector

    def __len__(self) -> int:
        return len(self.vectors)

    def of_texels(self, mv: TexelVectors) -> TexelVectors:
        """``mv``'s texels deduplicated down to these representatives (what the fit fits and writes)."""
        inverse = self.of_vector[mv.inverse] if mv.shape else mv.inverse
        return replace(mv, unique=self.vectors, inverse=inverse)


def _light(rows: Tensor, wi: Tensor, wo: Tensor) -> Tensor:
    """log(1 + g) of the analytic model of ``rows`` (N, 22), g = f cos + T c cos / pi (the fit error's measure)."""
    bsdf = LayeredBsdf(params_from_vectors(rows), torch.ones(1, 3))
    diffuse = GREY_BASE * wo[:, 2:3].clamp(min=0.0) / math.pi
    return torch.log1p(bsdf.eval_neural_part(wi, wo) + bsdf.transmission(wi) * diffuse)


def appearance_weights(model: NeuralModel, vectors: np.ndarray, counts: np.ndarray, seed: int = 0) -> np.ndarray:
    """(22,) per normalised parameter, the RMS change of log(1 + reflected light) per unit of it, over a
    count-weighted sample of ``vectors`` (their texels' share) at the same directions before and after."""
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(vectors), METRIC_VECTORS, replace=True, p=counts / counts.sum())
    pool = fitting_pool(model, vectors[pick])
    gen = torch.Generator().manual_seed(seed)
    b = make_batch(pool, len(pool) * METRIC_DIRECTIONS, gen, torch.arange(len(pool)).repeat(METRIC_DIRECTIONS))
    lo, hi = (torch.as_tensor(np.asarray(x, np.float32)) for x in bounds())
    weights = np.zeros(pool.shape[1])
    with torch.no_grad():
        before = _light(b.vectors, b.wi, b.wo)
        for j in range(pool.shape[1]):
            step = METRIC_DELTA * (hi[j] - lo[j])
            moved = b.vectors.clone()  # moved inwards from the upper bound, so it stays in the schema's range
            moved[:, j] = torch.where(moved[:, j] + step <= hi[j], moved[:, j] + step, moved[:, j] - step)
            weights[j] = float((_light(moved, b.wi, b.wo) - before).square().mean().sqrt()) / METRIC_DELTA
    return weights


def _nearest(points: Tensor, centres: Tensor) -> Tensor:
    """Index of each point's nearest centre (squared Euclidean), in blocks."""
    c2 = centres.square().sum(1)
    out = torch.empty(len(points), dtype=torch.long)
    for lo in range(0, len(points), CHUNK):
        p = points[lo:lo + CHUNK]
        out[lo:lo + CHUNK] = torch.addmm(c2[None, :], p, centres.T, alpha=-2.0).argmin(1)
    return out


def _premerge(coords: np.ndarray, counts: np.ndarray, cells: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Count-weighted cell means, cell counts and each point's cell, on a power-of-two grid (in
    metric units) with at most ``cells`` occupied cells: the finest such grid for a sample of
    the points, coarsened further only if all of them need it."""
    sample = coords[np.random.default_rng(0).choice(len(coords), min(len(coords), 8 * cells), replace=False)]
    step = max(float(np.ptp(coords, 0).max()), 1e-12) / 1024.0
    for points in (sample, coords):
        while len(unique_rows(np.floor(points / step).astype(np.int64))[0]) > cells:
            step *= 2.0
    keys, cell_of = unique_rows(np.floor(coords / step).astype(np.int64))
    weight = np.bincount(cell_of, counts, len(keys))
    means = np.stack([np.bincount(cell_of, counts * coords[:, j], len(keys)) for j in range(coords.shape[1])], 1)
    return means / weight[:, None], weight, cell_of


def coordinates(model: NeuralModel, vectors: np.ndarray, counts: np.ndarray, metric: str,
                seed: int = 0) -> np.ndarray:
    """(K, D) coordinates of ``vectors`` that the clustering measures distance in (``METRICS``)."""
    if metric == "encoder":
        with torch.no_grad():
            return np.concatenate([model.encoder(fitting_pool(model, vectors[lo:lo + CHUNK])).numpy()
                                   for lo in range(0, len(vectors), CHUNK)]).astype(np.float64)
    if metric not in METRICS:
        raise ValueError(f"metric must be one of {METRICS}, not {metric!r}")
    weights = appearance_weights(model, vectors, counts, seed) if metric == "appearance" else 1.0
    return normalise(vectors).astype(np.float64) * weights


def choose(model: NeuralModel, vectors: np.ndarray, counts: np.ndarray, budget: int, seed: int = 0,
           metric: str = "encoder") -> Representatives:
    """At most ``budget`` representatives of ``vectors`` (K, 22), each standing for ``counts`` texels:
    weighted k-means in ``metric``."""
    coords = coordinates(model, vectors, counts, metric, seed)
    cells, cell_weight, cell_of = _premerge(coords, counts.astype(np.float64), PREMERGE * budget)
    points, mass = torch.from_numpy(cells).float(), torch.from_numpy(cell_weight).float()
    gen = torch.Generator().manual_seed(seed)
    k = min(budget, len(points))
    centres = points[torch.multinomial(mass, k, replacement=False, generator=gen)]
    for _ in range(LLOYD_ITERATIONS):
        assign = _nearest(points, centres)
        total = torch.zeros(k).index_add_(0, assign, mass)
        moved = torch.zeros_like(centres).index_add_(0, assign, points * mass[:, None])
        keep = total > 0
        centres[keep] = moved[keep] / total[keep, None]
    assign = _nearest(points, centres).numpy()
    used, compact = np.unique(assign, return_inverse=True)
    of_vector = compact.ravel()[cell_of]
    mass_of = np.bincount(of_vector, counts, len(used))
    reps = np.stack([np.bincount(of_vector, counts * vectors[:, j], len(used)) for j in range(vectors.shape[1])], 1)
    return Representatives((reps / mass_of[:, None]).astype(np.float32), of_vector)


def transfer(model: NeuralModel, vectors: np.ndarray, reps: Representatives, z: Tensor,
             how: str = "nearest") -> Tensor:
    """Latents (K, 6) of every vector from the representatives' fitted latents ``z`` (B, 6)."""
    if how not in TRANSFERS:
        raise ValueError(f"transfer must be one of {TRANSFERS}, not {how!r}")
    of = torch.from_numpy(reps.of_vector)
    if how == "nearest":
        return z[of].clone()
    own, theirs = (torch.from_numpy(coordinates(model, v, np.ones(len(v)), "encoder")).float()
                   for v in (vectors, reps.vectors))
    return z[of] + own - theirs[of]


def draw_members(reps: Representatives, counts: np.ndarray, seed: int = 0) -> np.ndarray:
    """(B,) one member vector per representative, each drawn with its texels' share of the
    representative's (a weighted race, Efraimidis and Spirakis: the largest u^(1/count) wins)."""
    key = np.log(np.random.default_rng(seed).uniform(size=len(counts))) / np.maximum(counts, 1e-12)
    order = np.lexsort((-key, reps.of_vector))  # by representative, the winner first
    first = np.ones(len(order), bool)
    first[1:] = reps.of_vector[order[1:]] != reps.of_vector[order[:-1]]
    return order[first]
