"""Fitting's view of an enhanced material folder: its deduplicated texel vectors
(``core.texel_vectors``, shared with the add-on's numpy encoder) and the writer of a fit's
neural folder."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from richmat_addon.core import neural_folder
from richmat_addon.core.texel_vectors import QUANT, TexelVectors, read_vectors

if TYPE_CHECKING:
    from ..furnace import BoundedFit

MaterialVectors = TexelVectors
__all__ = ["QUANT", "MaterialVectors", "read_vectors", "write_fit"]


def write_fit(out: Path, mv: MaterialVectors, bounded: BoundedFit, decoder_sha256: str,
              fields: dict[str, Any], errors: np.ndarray | None = None) -> dict[str, Any]:
    """Write a fit's neural folder: latents at the material's texels, the energy scale where the
    furnace repaired, the fit error per vector (``errors``, (K,), ``error.py``) at the texels,
    and the counts and furnace result beside ``fields``; returns its record."""
    z, check = bounded.z, bounded.check
    scale = check.energy_scale()
    record = {"texels": int(len(mv.inverse)) if mv.shape else 1,
              "exact_unique_vectors": mv.exact_unique, "fitted_vectors": len(mv.unique),
              "cluster_bound": f"each texel within {mv.step:g} of its representative per normalised parameter",
              "furnace": dict(bounded.counts(), worst_albedo=float(check.albedo.max())), **fields}
    if mv.shape is None:
        return neural_folder.write(out, z[0].detach().numpy(), scale.detach().numpy(), decoder_sha256, record,
                                   fit_error=None if errors is None else errors[:1])
    return neural_folder.write(out, mv.texels(z), mv.texels(scale), decoder_sha256, record,
                               fit_error=None if errors is None else mv.texels(errors)[..., 0])
