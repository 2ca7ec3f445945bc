"""An enhanced material folder's per-texel parameter vectors, deduplicated for fitting.

Model no more than the material needs: texels with equal parameter vectors are
fitted once (exact dedupe), then vectors that agree to within a quantisation
step in the normalised parameter space are merged (every texel is within half a
step, ``QUANT / 2`` per normalised coordinate, of its representative). A
constant material stays one vector.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from richmat_addon.core.schema import CHANNEL_SLICES, PARAMS
from .networks import normalise_params

QUANT = 1.0 / 256.0


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
