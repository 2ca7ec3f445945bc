"""Training data for the universal decoder, generated on the fly (paper sec. 4.2).

Parameter vectors come from the enhancement rules themselves: ``enhance`` on
constant PBR inputs with random base colour, roughness and metalness, in four
themed classes (haze: Type 0; dust: Types 1 and 3; clearcoat: Types 2 and 3;
inner/subcutaneous scattering: Types 4 and 5), with the per-texel variation the
masks create (dust and coat weights between their floor and peak, partial
metalness). 20 % of vectors are "infill": uniform within the schema's bounds.
Directions: wi cosine-weighted with a share of grazing views; wo half uniform
over the hemisphere, half importance-sampled from the analytic model so that
narrow highlights are seen. Targets come from ``LayeredBsdf``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from richmat_addon.core.enhance import DUST_MASK_FLOOR, enhance
from richmat_addon.core.enhancement_types import DUST_TYPES, METAL_TYPES, TYPES, types_with
from richmat_addon.core.maps import ParamMap, PbrInputs
from richmat_addon.core.schema import CHANNEL_SLICES, bounds
from torch_models.brdf.model import LayeredBsdf, params_from_vectors

GGX_ALPHAS = ("alpha_core", "alpha_haze", "coat_alpha", "subsurf_alpha")
# Type 5's coat is drawn in the scattering class.
CLASSES: dict[str, tuple[int, ...]] = {
    "haze": tuple(t.index for t in TYPES if not t.lobes), "dust": types_with("dust"),
    "clearcoat": tuple(t for t in types_with("coat") if t in METAL_TYPES), "scattering": types_with("scatter")}
INFILL = 0.2


def _one(rng: np.random.Generator, theme: str) -> np.ndarray:
    """One packed parameter vector of a themed class."""
    types = CLASSES[theme]
    type_ = int(rng.choice(types))
    metal = 0.0 if TYPES[type_].dielectric_only else float(rng.choice([0.0, 1.0, rng.uniform()], p=[0.55, 0.35, 0.1]))
    pbr = PbrInputs("train", ParamMap.constant(*rng.uniform(0.0, 1.0, 3)),
                    ParamMap.constant(rng.uniform(0.0, 1.0)), ParamMap.constant(metal))
    mat = enhance(pbr, type_, int(rng.integers(1 << 31)))
    vec = np.concatenate([np.atleast_1d(mat.params[name].mean()) for name in CHANNEL_SLICES])
    if type_ in DUST_TYPES:  # dust masks: between the floor and the peak
        vec[CHANNEL_SLICES["dust_weight"]] *= rng.uniform(DUST_MASK_FLOOR, 1.0)
    if type_ in types_with("coat") and rng.uniform() < 0.3:  # damaged coat texels
        vec[CHANNEL_SLICES["coat_weight"]] = rng.uniform()
    return vec


def parameter_vectors(n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 22) vectors: themed classes in equal shares, ``INFILL`` of them uniform."""
    lo, hi = (np.array(b) for b in bounds())
    n_infill = int(round(INFILL * n))
    themes = list(CLASSES)
    themed = [_one(rng, themes[k % len(themes)]) for k in range(n - n_infill)]
    infill = lo + (hi - lo) * rng.uniform(size=(n_infill, len(lo)))
    out = np.concatenate([np.array(themed).reshape(-1, len(lo)), infill]).astype(np.float32)
    return out[rng.permutation(n)]


def angular_floor(vectors: np.ndarray, alpha_floor: float) -> Tensor:
    """(K, 22) vectors as the decoder is trained and fitted to draw them: every GGX alpha
    raised to ``alpha_floor``.

    A lobe narrower than the floor is a mirror at any resolution the preview ball or
    a texture shows (alpha 1e-3 against 1e-2 changes the ball by FLIP 0.004 median,
    0.02 worst), but to the decoder it is a peak a thousand times higher and ten
    times narrower, which a small shared network draws badly, and the whole
    material with it (docs/neural-material.md, "The angular floor and the relative loss")."""
    out = torch.as_tensor(np.asarray(vectors, np.float32)).clone()
    for name in GGX_ALPHAS:
        sl = CHANNEL_SLICES[name]
        out[:, sl] = out[:, sl].clamp(min=alpha_floor)
    return out


@dataclass
class Batch:
    index: Tensor  # (N,) rows of the pool
    vectors: Tensor  # (N, 22)
    wi: Tensor  # (N, 3)
    wo: Tensor  # (N, 3)
    f: Tensor  # (N, 3) f_neu * cos
    t: Tensor  # (N, 1)
    r: Tensor  # (N, 1)

    def to(self, device: torch.device) -> "Batch":
        return Batch(*(getattr(self, k).to(device) for k in self.__dataclass_fields__))


def view_directions(mu: Tensor) -> Tensor:
    """Local view directions (K, 3) in the xz plane at view cosines mu (K, 1): isotropic
    materials need no azimuth."""
    return torch.cat([(1 - mu * mu).clamp(min=0).sqrt(), torch.zeros_like(mu), mu], -1)


def cosine_hemisphere(n: int, gen: torch.Generator) -> Tensor:
    u = torch.rand(n, 2, generator=gen)
    r, phi = u[:, 0].sqrt(), 2 * torch.pi * u[:, 1]
    return torch.stack([r * phi.cos(), r * phi.sin(), (1 - u[:, 0]).clamp(min=1e-6).sqrt()], -1)


def _uniform_hemisphere(n: int, gen: torch.Generator) -> Tensor:
    v = torch.randn(n, 3, generator=gen)
    v[:, 2] = v[:, 2].abs()
    return v / v.norm(dim=-1, keepdim=True)


def make_batch(pool: Tensor, n: int, gen: torch.Generator, index: Tensor | None = None,
               weights: Tensor | None = None) -> Batch:
    """A batch of n (material, wi, wo) samples from a pool of parameter vectors: rows drawn at
    random (uniformly, or with probabilities ``weights``), or the rows ``index`` (n of them) when
    a caller needs set counts per vector."""
    if index is None and weights is not None:
        index = torch.multinomial(weights, n, replacement=True, generator=gen)
    elif index is None:
        index = torch.randint(len(pool), (n,), generator=gen)
    vectors = pool[index]
    wi = cosine_hemisphere(n, gen)
    grazing = torch.rand(n, generator=gen) < 0.2
    wi[grazing] = _uniform_hemisphere(int(grazing.sum()), gen)
    bsdf = LayeredBsdf(params_from_vectors(vectors), torch.ones(1, 3))
    with torch.no_grad():
        wo = _uniform_hemisphere(n, gen)
        important = torch.rand(n, generator=gen) < 0.5
        sampled = bsdf.sample(wi, torch.rand(n, 3, generator=gen))
        wo = torch.where(important[:, None] & (sampled[:, 2:3] > 0), sampled, wo)
        f = bsdf.eval_neural_part(wi, wo)
        t, r = bsdf.transmission(wi), bsdf.reflectance(wi)
    return Batch(index, vectors, wi, wo, f, t, r)
