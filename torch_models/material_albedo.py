"""How light an enhanced material is: its mean albedo, to compare an uplift with the PBR material it came from."""
from __future__ import annotations

import numpy as np
import torch

from richmat_addon.core.colour import LUMINANCE
from richmat_addon.core.maps import EnhancedMaterial

from .brdf.model import LayeredBsdf
from .demo_render import sample_map

VIEW_COSINES = 8  # Gauss-Legendre nodes over the view cosine


def texel_uvs(covered: np.ndarray) -> np.ndarray:
    """(N, 2) texture coordinates (v up) of the centres of the texels ``covered`` marks, an (H, W) bool
    array with the top row first, as the maps store them."""
    h, w = covered.shape
    rows, cols = np.nonzero(covered)
    return np.stack([(cols + 0.5) / w, 1.0 - (rows + 0.5) / h], 1)


def mean_albedo(mat: EnhancedMaterial, uv: np.ndarray) -> np.ndarray:
    """The RGB albedo under uniform white light (the view cosine weighted by 2 mu over the hemisphere:
    what a white furnace returns), averaged over the points ``uv`` (N, 2) of the material's texture space."""
    params = {name: sample_map(m, uv) for name, m in mat.params.items()}
    base = sample_map(mat.base_color, uv)
    n = len(uv)
    params = {k: v.expand(n, -1) for k, v in params.items()}
    bsdf = LayeredBsdf(params, base.expand(n, -1))
    nodes, weights = np.polynomial.legendre.leggauss(VIEW_COSINES)
    total = torch.zeros(n, 3)
    with torch.no_grad():
        for x, w in zip(nodes, weights):
            mu = 0.5 * (x + 1.0)
            wi = torch.tensor([[np.sqrt(1.0 - mu * mu), 0.0, mu]], dtype=torch.float32).expand(n, -1)
            per_lobe, diffuse = bsdf.lobe_albedos(wi)
            total += float(w * mu) * (sum(per_lobe, torch.zeros(n, 3)) + diffuse)  # 0.5 (dx) * 2 mu
    return total.mean(0).numpy()


def luminance(rgb: np.ndarray) -> float:
    return float(np.asarray(rgb) @ np.asarray(LUMINANCE))
