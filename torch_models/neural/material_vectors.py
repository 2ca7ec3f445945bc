"""An enhanced material folder's per-texel parameter vectors, deduplicated for fitting.

Model no more than the material needs: texels with equal parameter vectors are
fitted once (exact dedupe), then vectors that agree to within a quantisation
step in the normalised parameter space are merged (every texel is within half a
step, ``QUANT / 2`` per normalised coordinate, of its representative). A
constant material stays one vector.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from torch import Tensor

from richmat_addon.core import material_folder, neural_folder
from richmat_addon.core.schema import PARAMS
from .networks import normalise_params

if TYPE_CHECKING:
    from .energy import BoundedFit

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


def read_vectors(folder: Path) -> MaterialVectors:
    """Parameter vectors of an enhanced material folder (params.json + EXRs)."""
    mf = material_folder.read(folder)
    maps = {p.name: mf.map(p.name).value for p in PARAMS}
    shape = max((m.shape[:2] for m in maps.values() if m.ndim == 3), default=None, key=lambda s: s[0] * s[1])
    columns = []
    for p in PARAMS:
        m = maps[p.name]
        if m.ndim == 3:
            if m.shape[:2] != shape:  # nearest resampling to the largest map
                rows = (np.arange(shape[0]) * m.shape[0] // shape[0])[:, None]
                cols = (np.arange(shape[1]) * m.shape[1] // shape[1])[None, :]
                m = m[rows, cols]
            columns.append(m.reshape(-1, p.channels))
        else:
            columns.append(np.broadcast_to(m, ((shape[0] * shape[1]) if shape else 1, p.channels)))
    vectors = np.nan_to_num(np.concatenate(columns, 1).astype(np.float32))
    exact, inverse = np.unique(vectors, axis=0, return_inverse=True)
    keys = np.round(normalise_params(torch.from_numpy(exact)).numpy() / QUANT).astype(np.int64)
    merged_keys, merged_of_exact = np.unique(keys, axis=0, return_inverse=True)
    representatives = np.zeros((len(merged_keys), vectors.shape[1]), np.float32)
    np.add.at(representatives, merged_of_exact.ravel(), exact)
    representatives /= np.bincount(merged_of_exact.ravel())[:, None]
    texel_rep = merged_of_exact.ravel()[inverse.ravel()] if shape else np.zeros(0, np.int64)
    return MaterialVectors(shape, representatives, texel_rep, len(exact))


def write_fit(out: Path, mv: MaterialVectors, bounded: BoundedFit, decoder_sha256: str,
              fields: dict[str, Any]) -> dict[str, Any]:
    """Write a fit's neural folder: latents at the material's texels, the energy scale where the
    furnace repaired, and the counts and furnace result beside ``fields``; returns its record."""
    z, check = bounded.z, bounded.check
    scale = check.energy_scale()
    record = {"texels": int(len(mv.inverse)) if mv.shape else 1,
              "exact_unique_vectors": mv.exact_unique, "fitted_vectors": len(mv.unique),
              "cluster_bound": f"each texel within {QUANT / 2:g} of its representative per normalised parameter",
              "furnace": dict(bounded.counts(), worst_albedo=float(check.albedo.max())), **fields}
    if mv.shape is None:
        return neural_folder.write(out, z[0].detach().numpy(), scale.detach().numpy(), decoder_sha256, record)
    return neural_folder.write(out, mv.texels(z), mv.texels(scale), decoder_sha256, record)
