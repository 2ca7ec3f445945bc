"""Fit latents to parameter vectors against the frozen decoder (paper sec. 4.3).

Latents start from the encoder and are optimised with the loss the decoder was
trained with, on samples of the analytic model; ``material_vectors`` says which
vectors a material folder needs, ``energy`` checks what the fit wrote.
"""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace

import numpy as np
import torch
from torch import Tensor

from ..data import Batch, angular_floor, make_batch
from ..loss import decoder_loss
from ..model import NeuralModel

FIT_BATCH = 16384  # (texel, wi, wo) samples per Adam step at least, shared by the vectors fitted together
SAMPLES_PER_VECTOR = 4  # per Adam step and vector at least: a vector's samples do not shrink as textures grow
CHUNK_SAMPLES = 65536  # samples per forward pass at most; beyond, the vectors are stepped in chunks
FIT_BUFFER = 24  # batches of analytic targets drawn per fit, then reused


def fitting_pool(model: NeuralModel, vectors: np.ndarray) -> Tensor:
    """(K, 22) vectors as ``model`` was trained to draw them (its angular floor applied)."""
    return angular_floor(vectors, model.alpha_floor)


def fitting_loss(model: NeuralModel, z: Tensor, batch: Batch) -> Tensor:
    """The loss ``model`` was trained with (its relative term included), which fitting minimises."""
    return decoder_loss(model.decoder, z, batch, relative_weight=model.relative_weight, t_weight=model.t_weight)


def sample_plan(count: int, batch: int, per_vector: int) -> list[Tensor] | None:
    """Rows of each chunk's samples for ``count`` vectors, each ``per_vector`` times per step, in
    chunks of at most ``CHUNK_SAMPLES``; None where ``batch`` random rows give every vector that
    many on average (few vectors: they share one batch, as they always did)."""
    if per_vector * count <= batch:
        return None
    rows = max(1, CHUNK_SAMPLES // per_vector)
    return [torch.arange(lo, min(lo + rows, count)).repeat(per_vector) for lo in range(0, count, rows)]


def target_buffer(pool: Tensor, batch: int, per_vector: int, steps: int, gen: torch.Generator) -> list[list[Batch]]:
    """Per chunk, the batches of analytic targets a fit cycles through (see ``sample_plan``).

    Chunked buffers drop the vectors, which the loss does not read: at 1/256 a 1k
    texture has tens of thousands of vectors, and the buffer is most of a fit's memory."""
    draws = min(steps, FIT_BUFFER)
    plan = sample_plan(len(pool), batch, per_vector)
    if plan is None:
        return [[make_batch(pool, batch, gen) for _ in range(draws)]]
    return [[replace(make_batch(pool, len(rows), gen, rows), vectors=pool[:0]) for _ in range(draws)] for rows in plan]


def fit_latents(model: NeuralModel, vectors: np.ndarray, steps: int, batch: int = FIT_BATCH, seed: int = 0,
                start: Tensor | None = None, progress=None,  # type: ignore[no-untyped-def]
                per_vector: int = SAMPLES_PER_VECTOR) -> Tensor:
    """Latents (K, 6) of K parameter vectors, from the encoder (or ``start``), optimised ``steps`` times.

    Each step sees ``batch`` samples or ``per_vector`` per vector, whichever is more, so
    that a vector's fit does not depend on how many others it is fitted with. Analytic
    targets cost far more than a decoder step, so ``FIT_BUFFER`` batches are drawn once
    and cycled through (fewer when there are fewer steps). Adam is per coordinate, so
    stepping the chunks' summed gradients fits each chunk as if it were fitted alone.
    """
    pool = fitting_pool(model, vectors)
    with torch.no_grad():
        z0 = model.encoder(pool) if start is None else start
    z = z0.clone().requires_grad_(True)
    opt = torch.optim.Adam([z], lr=1e-2)
    gen = torch.Generator().manual_seed(seed)
    chunks = target_buffer(pool, batch, per_vector, steps, gen)
    with deterministic():
        for step in range(steps):
            opt.zero_grad()
            total, samples = 0.0, 0
            for buffer in chunks:
                b = buffer[step % len(buffer)]
                loss = fitting_loss(model, z[b.index], b)
                loss.backward()
                total, samples = total + loss.item() * len(b.index), samples + len(b.index)
            total /= samples
            opt.step()
            if progress is not None:
                progress(step, total, z.detach())
    return z.detach()


def held_out_loss(model: NeuralModel, vectors: np.ndarray, z: Tensor, samples: int = 256, seed: int = 1) -> float:
    """Mean over the vectors of each one's fitting loss on ``samples`` fresh directions: how well
    latents ``z`` fit, with every vector weighed alike whatever the others."""
    pool = fitting_pool(model, vectors)
    gen = torch.Generator().manual_seed(seed)
    rows = max(1, CHUNK_SAMPLES // samples)
    losses = []
    with torch.no_grad():
        for lo in range(0, len(pool), rows):
            index = torch.arange(lo, min(lo + rows, len(pool))).repeat(samples)
            b = make_batch(pool, len(index), gen, index)
            losses.append(fitting_loss(model, z[b.index], b).item() * len(index))
    return sum(losses) / (len(pool) * samples)


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
