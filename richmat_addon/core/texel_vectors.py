"""An enhanced material folder's per-texel parameter vectors, deduplicated, in numpy.

Model no more than the material needs: texels with equal parameter vectors are
encoded or fitted once (exact dedupe), then vectors that agree to within a
quantisation step in the normalised parameter space are merged into their mean
(every texel is within one step, ``QUANT`` per normalised coordinate, of its
representative: both lie in the same cell). A constant material stays one vector. Torch-free, so the
add-on's numpy encoder in a stock Blender dedupes as the torch fit does.

Past ``FIT_BUDGET`` merged vectors the fit chooses representatives instead
(``torch_models/neural/fit/representatives.py``), so its cost stops growing with the texture.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import material_folder
from .schema import PARAMS, bounds

QUANT = 1.0 / 256.0
# Vectors a fit fits at most: past it, representatives (torch_models/neural/fit/representatives.py).
# The fit's 16 384-sample step then gives each of them 16 samples where a per-vector fit gives 4:
# fewer, better-fitted representatives err less than more, noisier ones, and choosing them is
# cheaper (bench/neural/fit_bounded.py charts the choice against 256-16 384 and the per-vector fit).
FIT_BUDGET = 1024


def normalise(vectors: np.ndarray) -> np.ndarray:
    """Packed (N, 22) schema vectors mapped to [0, 1] by the schema's bounds (float32, as the networks see them)."""
    lo, hi = (np.asarray(b, np.float32) for b in bounds())
    return (np.asarray(vectors, np.float32) - lo) / (hi - lo)


@dataclass
class TexelVectors:
    """Per-texel parameter vectors of a material folder, deduplicated."""

    shape: tuple[int, int] | None  # texture size, or None for a constant material
    unique: np.ndarray  # (K, 22) representatives
    inverse: np.ndarray  # (H*W,) representative of every texel (empty when constant)
    exact_unique: int  # distinct vectors before merging
    step: float = QUANT  # the merging step in the normalised parameter space

    def texels(self, per_vector: np.ndarray) -> np.ndarray:
        """Per-representative values (K, C) scattered to the texture, (H, W, C); any array-like
        (a torch tensor too)."""
        assert self.shape is not None, "a constant material has no texels"
        per_vector = np.asarray(per_vector)
        values = per_vector.reshape(len(per_vector), -1)[self.inverse]
        return np.ascontiguousarray(values.reshape(*self.shape, -1))


def nearest_resize(image: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(H, W, C) ``image`` resampled to ``shape`` by the nearest texel (itself when it has that size)."""
    if image.shape[:2] == tuple(shape):
        return image
    rows = (np.arange(shape[0]) * image.shape[0] // shape[0])[:, None]
    cols = (np.arange(shape[1]) * image.shape[1] // shape[1])[None, :]
    return image[rows, cols]


def texel_matrix(folder: Path) -> tuple[tuple[int, int] | None, np.ndarray]:
    """(texture size or None, every texel's packed vector (H*W or 1, 22)) of an enhanced material folder."""
    mf = material_folder.read(folder)
    maps = {p.name: mf.map(p.name).value for p in PARAMS}
    shape = max((m.shape[:2] for m in maps.values() if m.ndim == 3), default=None, key=lambda s: s[0] * s[1])
    columns = []
    for p in PARAMS:
        m = maps[p.name]
        if m.ndim == 3:
            columns.append(nearest_resize(m, shape).reshape(-1, p.channels))
        else:
            columns.append(np.broadcast_to(m, ((shape[0] * shape[1]) if shape else 1, p.channels)))
    return shape, np.nan_to_num(np.concatenate(columns, 1).astype(np.float32))


def unique_rows(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(distinct rows, index of each row's) of a 2-D array, in the byte order of the rows.

    Each row is compared as one byte string of its varying columns only (a material holds most
    parameters constant, and the string's length is what the sort pays for), which sorts many
    times faster than ``np.unique(axis=0)`` on a texture's 22 columns."""
    rows = np.ascontiguousarray(rows)
    varying = np.flatnonzero((rows != rows[:1]).any(0)) if len(rows) else np.zeros(0, np.int64)
    keys = np.ascontiguousarray(rows[:, varying] if len(varying) else rows[:, :1])
    as_bytes = keys.view(np.dtype((np.void, keys.dtype.itemsize * keys.shape[1]))).ravel()
    _, first, inverse = np.unique(as_bytes, return_index=True, return_inverse=True)
    return rows[first], inverse.ravel()


def read_vectors(folder: Path, step: float = QUANT) -> TexelVectors:
    """Parameter vectors of an enhanced material folder (params.json + EXRs), merged at ``step``."""
    return dedupe(*texel_matrix(folder), step)


def dedupe(shape: tuple[int, int] | None, vectors: np.ndarray, step: float = QUANT) -> TexelVectors:
    """Texel vectors (H*W or 1, 22) of a texture of ``shape``, deduplicated and merged at ``step``."""
    exact, inverse = unique_rows(vectors + 0.0)  # + 0.0: -0.0 and 0.0 are one value
    keys = np.round(normalise(exact) / step).astype(np.int64)
    merged_keys, merged_of_exact = unique_rows(keys)
    representatives = np.zeros((len(merged_keys), vectors.shape[1]), np.float32)
    np.add.at(representatives, merged_of_exact.ravel(), exact)
    representatives /= np.bincount(merged_of_exact.ravel())[:, None]
    texel_rep = merged_of_exact.ravel()[inverse.ravel()] if shape else np.zeros(0, np.int64)
    return TexelVectors(shape, representatives, texel_rep, len(exact), step)
