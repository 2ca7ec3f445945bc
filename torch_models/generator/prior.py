"""The uplift prior: the procedural enhancement that the generator refines.

The enhancement rules (``core.enhance``) already turn a mesh's PBR material into a
plausible enhanced one of the type the prompt names. The settings a caption words
("light dust", "heavy haze") are set from the prompt's strength words (``prompt.Reading
.settings``); the rest are drawn with fixed draws (``PRIOR_SEED``). The generator starts
from that uplift and learns only the residual the caption calls for: its input views carry the prior's
latents, its target is reference minus prior, and ``generate`` adds the projected
residual to the prior texture, which is exact at every texel (no view blur).

A mesh without roughness and metalness maps is uplifted as a dielectric of
roughness ``UNKNOWN_ROUGHNESS``; training sees that prior whenever it drops the two
maps, so one model serves both kinds of input.
"""
from __future__ import annotations

import numpy as np

from richmat_addon.core.enhance import enhance, resolve_type
from richmat_addon.core.maps import EnhancedMaterial, ParamMap, PbrInputs
from .encoding import latent_texture
from .mesh_input import resize

PRIOR_SEED = 2 ** 40  # far from every corpus object's own draws (corpus.enhancement_seed)
PRIOR_NAME = "richmat-prior"  # the draws depend on the material's name: one fixed name, whatever the file says
UNKNOWN_ROUGHNESS = 0.5


def pbr_inputs(base_color: np.ndarray, roughness_metalness: np.ndarray | None, size: tuple[int, int],
               name: str = PRIOR_NAME) -> PbrInputs:
    """A material's maps ((H, W, C) texture-space images, constants (1, 1, C)) as the enhancer's inputs
    at ``size``; ``roughness_metalness`` None means unknown (a dielectric of ``UNKNOWN_ROUGHNESS``)."""
    def as_map(image: np.ndarray) -> ParamMap:
        if image.shape[:2] == (1, 1):
            return ParamMap.constant(*image.reshape(-1))
        return ParamMap(resize(image, size).astype(np.float32))

    if roughness_metalness is None:
        rough, metal = ParamMap.constant(UNKNOWN_ROUGHNESS), ParamMap.constant(0.0)
    else:
        rough, metal = as_map(roughness_metalness[..., :1]), as_map(roughness_metalness[..., 1:2])
    return PbrInputs(name, as_map(base_color), rough, metal)


def prior_material(base_color: np.ndarray, roughness_metalness: np.ndarray | None, type_: int,
                   normals: np.ndarray, positions: np.ndarray, seed: int = PRIOR_SEED,
                   name: str = PRIOR_NAME, fixed: dict[str, float] | None = None) -> EnhancedMaterial:
    """The enhanced material the prior encodes, at the normals' texture size; ``seed`` and ``name``
    pick other draws (a reference uplift with a material's own draws, bench/generator/generate_prompts.py);
    ``fixed`` settings replace their draws (the prompt's strength words, ``prompt.Reading.settings``)."""
    pbr = pbr_inputs(base_color, roughness_metalness, normals.shape[:2], name)
    resolved, _ = resolve_type(pbr, type_, seed)  # a dielectric-only type on a metal: its metal twin
    return enhance(pbr, resolved, seed, ParamMap(normals.astype(np.float32)), ParamMap(positions.astype(np.float32)),
                   fixed=fixed)


def prior_latents(base_color: np.ndarray, roughness_metalness: np.ndarray | None, type_: int,
                  normals: np.ndarray, positions: np.ndarray, fixed: dict[str, float] | None = None) -> np.ndarray:
    """(H, W, 6) the shipped encoder's latents of the prior material, at the normals' texture size."""
    material = prior_material(base_color, roughness_metalness, type_, normals, positions, fixed=fixed)
    return latent_texture(material, normals.shape[:2])
