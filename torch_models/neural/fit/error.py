"""The fit error the add-on shows: how far each fitted latent renders from the analytic material
it encodes, per texel and as one number per material (docs/addon.md, "Fit error").

The measure is the relative error of the reflected light g = s f_neu cos + T c cos / pi (the
diffuse base with a mid-grey base colour: the vectors carry none) on a tone curve, log(1 + g):
sum |log(1 + g_decoded) - log(1 + g_analytic)| / sum log(1 + g_analytic) over the samples and
channels of one vector. The tone curve keeps a highlight's peak from outweighing the rest, as a
tone-mapped render does (in linear light the peak's samples decided the number, and it rose as
the fit, which minimises a log error, went on). Directions are fresh samples drawn as the fit
draws them (view cosine-weighted with grazing views, outgoing half uniform, half importance-
sampled from the analytic model): the error a render sees, not the loss the optimiser saw. The grades it is read with are in ``core/fit_error.py``.
"""
from __future__ import annotations

import math

import numpy as np
import torch

from ..data import make_batch
from ..model import NeuralModel
from .latents import fitting_pool

SAMPLE_BUDGET = 1 << 18  # direction samples per material: about a fifth of what a 300-step fit draws
MIN_SAMPLES, MAX_SAMPLES = 8, 256  # per vector: the budget is shared, within these bounds
GREY_BASE = 0.5  # base colour of the diffuse base T c / pi in the measure
CHUNK = 1 << 15


def samples_per_vector(vectors: int) -> int:
    """Direction samples per vector: the budget shared among ``vectors``, clamped."""
    return int(min(MAX_SAMPLES, max(MIN_SAMPLES, SAMPLE_BUDGET // max(vectors, 1))))


def vector_errors(model: NeuralModel, vectors: np.ndarray, z: torch.Tensor, energy_scale: torch.Tensor,
                  seed: int = 0) -> np.ndarray:
    """(K,) relative error of the reflected light of latents z (K, 6), scaled by ``energy_scale``
    (K,), against the analytic vectors (K, 22) they were fitted to."""
    pool = fitting_pool(model, vectors)
    per = samples_per_vector(len(pool))
    gen = torch.Generator().manual_seed(seed + 65_537)
    diff, total = torch.zeros(len(pool)), torch.zeros(len(pool))
    rows = torch.arange(len(pool)).repeat_interleave(per)
    with torch.no_grad():
        for k0 in range(0, len(rows), CHUNK):
            index = rows[k0:k0 + CHUNK]
            b = make_batch(pool, len(index), gen, index=index)
            f, t, _ = model.decoder(z[index], b.wi, b.wo)
            diffuse = GREY_BASE * b.wo[:, 2:3].clamp(min=0.0) / math.pi
            decoded = energy_scale[index, None] * f + t * diffuse
            analytic = b.f + b.t * diffuse
            diff.index_add_(0, index, (torch.log1p(decoded) - torch.log1p(analytic)).abs().sum(-1))
            total.index_add_(0, index, torch.log1p(analytic).sum(-1))
    return (diff / total.clamp(min=1e-6)).numpy()
