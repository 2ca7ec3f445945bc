"""An enhanced material as a latent texture, through the shipped encoder.

Shared by the corpus (its targets) and the uplift prior (its conditioning
channels); it lives below both so that the corpus imports the prior and the prior
never imports the corpus back.
"""
from __future__ import annotations

import numpy as np
import torch

from richmat_addon.core.maps import EnhancedMaterial
from richmat_addon.core.schema import PARAMS


def pack_vectors(material: EnhancedMaterial, shape: tuple[int, int]) -> np.ndarray:
    """Per-texel schema vectors (H*W, 22) of an enhanced material; constants broadcast."""
    n = shape[0] * shape[1]
    cols = [np.broadcast_to(material.params[p.name].value.reshape(-1, p.channels), (n, p.channels))
            for p in PARAMS]
    return np.concatenate(cols, 1).astype(np.float32)


def latent_texture(material: EnhancedMaterial, shape: tuple[int, int], fit_steps: int = 0) -> np.ndarray:
    """(H, W, 6) latents: the shipped encoder per distinct texel vector, optionally refined by the fit."""
    from ..neural import trained
    from ..neural.fit.latents import fit_latents

    vectors = pack_vectors(material, shape)
    unique, inverse = np.unique(vectors, axis=0, return_inverse=True)
    model = trained.load()
    if fit_steps:
        z = fit_latents(model, unique, fit_steps, batch=4096)
    else:
        with torch.no_grad():
            z = model.encoder(torch.from_numpy(unique))
    return z.numpy()[inverse.ravel()].reshape(*shape, -1)
