"""The fit's samples are per vector: a vector fits as well among many others as alone."""
from __future__ import annotations

import numpy as np

from richmat_addon.core.schema import bounds
from torch_models.neural import trained
from torch_models.neural.data import parameter_vectors
from torch_models.neural.fit.latents import fit_latents, fitting_pool, held_out_loss

N, COPIES, STEPS, BATCH, PER_VECTOR = 32, 8, 100, 128, 16


def jittered_copies(vectors: np.ndarray, copies: int, rng: np.random.Generator) -> np.ndarray:
    """``vectors`` followed by copies - 1 copies of them, each parameter moved by up to 2 % of its range."""
    lo, hi = (np.array(b, np.float32) for b in bounds())
    moved = np.tile(vectors, (copies - 1, 1)) + (hi - lo) * rng.uniform(-0.02, 0.02, size=((copies - 1) * len(vectors), len(lo)))
    return np.concatenate([vectors, np.clip(moved, lo, hi).astype(np.float32)])


def test_a_vector_fits_as_well_among_eight_times_as_many() -> None:
    rng = np.random.default_rng(3)
    model = trained.load(trained.SHIPPED)
    alone = parameter_vectors(N, rng)
    crowd = jittered_copies(alone, COPIES, rng)

    def held_out(vectors: np.ndarray, per_vector: int) -> float:
        z = fit_latents(model, vectors, STEPS, batch=BATCH, per_vector=per_vector)
        return held_out_loss(model, alone, z[:N])

    start = held_out_loss(model, alone, model.encoder(fitting_pool(model, alone)).detach())
    per_vector = held_out(alone, PER_VECTOR), held_out(crowd, PER_VECTOR)
    shared = held_out(alone, 0), held_out(crowd, 0)  # one batch of BATCH samples, however many vectors
    assert per_vector[0] < 0.9 * start  # the fit did fit
    assert abs(per_vector[1] - per_vector[0]) < 0.05 * per_vector[0]  # measured 1.7 %
    assert shared[1] > 1.15 * shared[0]  # measured 33 % worse: an eighth of the samples each
