"""Fit latents to parameter vectors against the frozen decoder (paper sec. 4.3).

Latents start from the encoder and are optimised with the loss the decoder was
trained with, on samples of the analytic model; ``material_vectors`` says which
vectors a material folder needs, ``energy`` checks what the fit wrote.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numpy as np
import torch
from torch import Tensor

from .data import Batch, angular_floor, make_batch
from .loss import decoder_loss
from .weights import NeuralModel

FIT_BATCH = 16384  # (texel, wi, wo) samples per Adam step, shared by all vectors fitted together
FIT_BUFFER = 24  # batches of analytic targets drawn per fit, then reused


def fitting_pool(model: NeuralModel, vectors: np.ndarray) -> Tensor:
    """(K, 22) vectors as ``model`` was trained to draw them (its angular floor applied)."""
    return angular_floor(vectors, model.alpha_floor)


def fitting_loss(model: NeuralModel, z: Tensor, batch: Batch) -> Tensor:
    """The loss ``model`` was trained with (its relative term included), which fitting minimises."""
    return decoder_loss(model.decoder, z, batch, relative_weight=model.relative_weight, t_weight=model.t_weight)


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
