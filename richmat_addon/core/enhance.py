"""Procedural enhancement: simple PBR maps to the 22 parameter maps (paper sec. 3.2).

numpy only, so the add-on can uplift inside a stock Blender. Per-material scalars
are drawn from a generator seeded by (seed, material name), so the same input and
seed always give the same material. Constant inputs give constant outputs: maps
are plain numpy arrays of shape (C,) or (H, W, C) and every rule is elementwise.
Ranges are documented (with which are ours) in docs/enhancement.md.
"""
from __future__ import annotations

import hashlib
import warnings
from collections.abc import Callable

import numpy as np

from . import masks
from .colour import LUMINANCE
from .enhancement_types import (BASE_FAMILY, DIELECTRIC_ONLY, FAMILIES, METAL_REMAP, METAL_TYPES, TYPE_MIX,
                                TYPES, index_ranges)
from .maps import EnhancedMaterial, ParamMap, PbrInputs
from .schema import PARAM_BY_NAME, PARAMS

DUST_MASK_FLOOR = 0.35  # dust weight between mask features, as a share of the peak
DUST_MASK_SCALE = (1.0, 3.0)  # the range of the triplanar dust mask's scale (features per unit), drawn per material
METALLIC_THRESHOLD = 0.5  # mean metalness above which a material counts as a metal
# Auto's touch: the rules add about the same reflectance whatever the base (a clear coat's Fresnel ~0.09 of
# uniform light, white dust and fuzz, scatter lifted toward white), which greys a dark base. Auto scales the
# enhancement per texel by (base luminance / FULL_TOUCH_LUMINANCE)^TOUCH_POWER, at most 1 (linear luminance;
# 0.18 is sRGB 0.46): a tyre at 0.02 keeps 4 % of it, a mid-grey paint all of it.
FULL_TOUCH_LUMINANCE = 0.18
TOUCH_POWER = 1.5


def is_metallic(pbr: PbrInputs) -> bool:
    return float(np.nan_to_num(pbr.metalness.mean()[0])) > METALLIC_THRESHOLD


def _rng(seed: int, name: str, purpose: str) -> np.random.Generator:
    digest = hashlib.sha256(f"{name}\0{purpose}".encode()).digest()
    return np.random.default_rng([seed, int.from_bytes(digest[:8], "little")])


def _draw(rng: np.random.Generator, family: str, fixed: dict[str, float]) -> dict[str, float]:
    """The settings ``family`` draws (``Family.draws``), in its order, those in ``fixed`` replaced after
    their draw (so fixing one leaves every other draw as it was)."""
    return {d.key: fixed.get(d.key, rng.uniform(d.lo, d.hi)) for d in FAMILIES[family].draws}


def resolve_type(pbr: PbrInputs, requested: int | str, seed: int) -> tuple[int, str]:
    """The type to apply and a note; 'auto' draws from the paper's mix.

    A dielectric-only type requested on a metal comes back remapped (4 -> 1,
    5 -> 3) with a note saying so; callers that must refuse compare the result
    with what they asked for.
    """
    metal = is_metallic(pbr)
    if requested == "auto":
        probs = np.array(TYPE_MIX)
        if metal:
            probs[list(DIELECTRIC_ONLY)] = 0.0
        type_ = int(_rng(seed, pbr.name, "type").choice(len(TYPES), p=probs / probs.sum()))
        return type_, f"auto: type {type_}" + (f" (metal: types {index_ranges(DIELECTRIC_ONLY)} excluded)"
                                               if metal else "")
    type_ = int(requested)
    if not 0 <= type_ < len(TYPES):
        raise ValueError(f"unknown enhancement type {requested!r}; use {index_ranges(range(len(TYPES)))} or 'auto'")
    if metal and type_ in DIELECTRIC_ONLY:
        return METAL_REMAP[type_], (f"type {type_} is for dielectrics and {pbr.name!r} is metallic "
                                    f"(mean metalness > {METALLIC_THRESHOLD}); used type "
                                    f"{METAL_REMAP[type_]} instead")
    return type_, ""


def _clean(m: ParamMap, lo: float, hi: float, what: str, material: str) -> np.ndarray:
    """Replace NaN/inf and clamp out-of-range texels, warning with a count."""
    v = m.value
    bad = ~np.isfinite(v)
    out = (v < lo) | (v > hi)
    if bad.any() or out.any():
        warnings.warn(f"{material}: {what}: {int(bad.sum())} non-finite and {int(out.sum())} "
                      f"out-of-range values replaced/clamped to [{lo}, {hi}]", stacklevel=3)
    return np.clip(np.nan_to_num(v, nan=(lo + hi) / 2, posinf=hi, neginf=lo), lo, hi)


def _fit(name: str, value: np.ndarray | float) -> ParamMap:
    p = PARAM_BY_NAME[name]
    v = np.clip(np.asarray(value, np.float32), p.lo, p.hi)
    if v.ndim == 0:
        v = v.reshape(1)
    if p.channels == 1 and v.ndim == 2:
        v = v[..., None]
    return ParamMap(v)


def _mask_shape(pbr: PbrInputs, normals: ParamMap | None) -> tuple[int, int] | None:
    """(H, W) of the largest input texture, the mask's texture space; None when nothing gives one."""
    shapes = [m.shape for m in (pbr.base_color, pbr.roughness, pbr.metalness, normals)
              if m is not None and m.shape]
    return max(shapes, key=max) if shapes else None


def _uv_mask(mask: Callable[[int, masks.Rng], np.ndarray], shape: tuple[int, int], rng: masks.Rng) -> np.ndarray:
    """A square tileable mask made at the texture's longer side and cut to its (H, W), so a
    non-square texture gets a mask of its own shape with square features."""
    h, w = shape
    return mask(max(h, w), rng)[:h, :w]


def _dust_weight(pbr: PbrInputs, rng: np.random.Generator, peak: float,
                 normals: ParamMap | None, positions: ParamMap | None,
                 settings: dict) -> np.ndarray:
    """Upward-facing factor times a triplanar mask; UV-space mask without geometry."""
    kind = str(rng.choice(sorted(masks.DUST_MASKS)))
    shape = _mask_shape(pbr, normals)
    if shape is None:  # factor-only material without world maps: no texture to put a mask in
        settings["dust_mask"] = "none: no texture space"
        return np.float32(peak * DUST_MASK_FLOOR)
    settings["dust_mask"] = kind
    # Dust still settles between the features: the mask modulates, never zeroes.
    if normals is None or positions is None or normals.is_constant:
        settings["dust_geometry"] = "none: mask in UV space, surface assumed facing up"
        mask = DUST_MASK_FLOOR + (1.0 - DUST_MASK_FLOOR) * _uv_mask(masks.DUST_MASKS[kind], shape, rng)
        return peak * mask[..., None]
    mask = DUST_MASK_FLOOR + (1.0 - DUST_MASK_FLOOR) * masks.DUST_MASKS[kind](max(shape), rng)
    n = normals.value / np.maximum(np.linalg.norm(normals.value, axis=-1, keepdims=True), 1e-12)
    up = np.clip(n[..., 2:3] / 0.7, 0.0, 1.0) ** 2
    tri = masks.triplanar(mask, positions.value, n, scale=rng.uniform(*DUST_MASK_SCALE))[..., None]
    settings["dust_geometry"] = "world normals and positions"
    return peak * up * tri


def auto_touch(pbr: PbrInputs) -> ParamMap:
    """How much of the enhancement Auto applies, per texel of the base colour (a constant for a constant
    base): full on a base of mid-grey luminance or lighter, less on darker ones (tyres, dark glass, dark
    paint), which the rules' light dust, haze and scatter would otherwise turn grey."""
    lum = np.nan_to_num(np.clip(pbr.base_color.value, 0.0, 1.0)) @ np.asarray(LUMINANCE, np.float32)
    return ParamMap((np.clip(lum / FULL_TOUCH_LUMINANCE, 0.0, 1.0) ** TOUCH_POWER)[..., None].astype(np.float32))


def _resampled(value: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """A (C,) or (H, W, C) array on the grid of ``shape`` (nearest texel), so maps of different sizes mix."""
    if value.ndim == 1 or len(shape) == 1 or value.shape[:2] == tuple(shape[:2]):
        return value
    h, w = shape[:2]
    rows = (np.arange(h) * value.shape[0]) // h
    cols = (np.arange(w) * value.shape[1]) // w
    return value[rows][:, cols]


def scale_enhancement(mat: EnhancedMaterial, plain: EnhancedMaterial, amount: ParamMap) -> EnhancedMaterial:
    """``mat`` moved toward ``plain`` (its PBR material in the same model, ``baseline``): every parameter
    ``plain + amount (enhanced - plain)``, so lobe weights scale by ``amount`` and 0 gives back the PBR
    material. ``amount`` is a constant or a map over the base colour's texels."""
    params = {}
    for name, m in mat.params.items():
        e, b = m.value, plain.params[name].value
        shape = max((e.shape, b.shape, amount.value.shape), key=len)
        e, b, a = (_resampled(v, shape) for v in (e, b, amount.value))
        params[name] = _fit(name, b + a * (e - b)).collapse()  # a lerp of equal texels stays a constant
    return EnhancedMaterial(mat.name, mat.type, mat.seed, mat.base_color, params, mat.settings)


def enhance(pbr: PbrInputs, type_: int | str = "auto", seed: int = 0,
            world_normals: ParamMap | None = None,
            world_positions: ParamMap | None = None, amount: float = 1.0, touch: bool = False,
            fixed: dict[str, float] | None = None) -> EnhancedMaterial:
    """Enhance one material, scaled toward the PBR material by ``amount`` in [0, 1] (1: the rules as drawn),
    times ``auto_touch`` per texel with ``touch`` (what Auto asks for); ``fixed`` settings replace their draws
    (a prompt's strength words, ``prompt.Reading.settings``). Types 4/5 on a metal raise ValueError (see
    resolve_type)."""
    resolved, note = resolve_type(pbr, type_, seed)
    if type_ != "auto" and resolved != int(type_):
        raise ValueError(f"{pbr.name}: {note}. Choose a type in {index_ranges(METAL_TYPES)} for metals.")
    rng = _rng(seed, pbr.name, "params")
    base = _clean(pbr.base_color, 0.0, 1.0, "base colour", pbr.name)
    rough = _clean(pbr.roughness, 0.0, 1.0, "roughness", pbr.name)
    metal = _clean(pbr.metalness, 0.0, 1.0, "metalness", pbr.name)

    fixed = fixed or {}
    s = {"type": resolved, "type_note": note, "seed": seed, **_draw(rng, BASE_FAMILY, fixed)}
    lum = base @ np.array(LUMINANCE, np.float32)
    values: dict[str, np.ndarray | float] = {
        "spec_color": base, "edge_tint": s["edge_tint"], "metalness": metal,
        "alpha_core": rough ** s["p"], "alpha_haze": np.minimum(1.0, s["s"] * rough ** s["q"]),
        "haze_weight": s["haze_weight"], "diel_ior": s["diel_ior"],
    }
    if metal.ndim == 1 and metal[0] == 0.0:
        del values["spec_color"]  # no conductor anywhere: keep the constant default
    lobes = TYPES[resolved].lobes
    if "dust" in lobes:
        s.update(_draw(rng, "dust", fixed))
        values["dust_weight"] = _dust_weight(pbr, rng, s["dust_peak"], world_normals,
                                             world_positions, s)
        values["dust_roughness"] = s["dust_roughness"]
    if "fuzz" in lobes:
        s.update(_draw(rng, "fuzz", fixed))
        values["dust_weight"], values["dust_roughness"] = s["fuzz_weight"], s["fuzz_roughness"]
    if "coat" in lobes:
        s.update(_draw(rng, "coat", fixed), coat_damage=str(rng.choice(["none"] + sorted(masks.DAMAGE_MASKS))))
        damage_shape = _mask_shape(pbr, world_normals)
        if damage_shape is None:
            s["coat_damage"] = "none"
        values["coat_ior"], values["coat_alpha"] = s["coat_ior"], s["coat_alpha"]
        values["coat_weight"] = 1.0 if s["coat_damage"] == "none" else \
            1.0 - _uv_mask(masks.DAMAGE_MASKS[s["coat_damage"]], damage_shape, rng)
    if "scatter" in lobes:
        s.update(_draw(rng, "scatter", fixed))
        # Gentle desaturation: 30 % toward grey, then lifted a little toward white.
        values["scatter_color"] = 0.85 * (0.7 * base + 0.3 * lum[..., None]) + 0.15
        values.update(inner_weight=s["inner_weight"], inner_roughness=s["inner_roughness"],
                      subsurf_weight=1.0, subsurf_alpha=s["subsurf_alpha"],
                      subsurf_ior=s["subsurf_ior"])

    params = {p.name: _fit(p.name, values.get(p.name, p.default)) for p in PARAMS}
    settings = {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in s.items()}
    mat = EnhancedMaterial(pbr.name, resolved, seed, ParamMap(base), params, settings)
    if amount == 1.0 and not touch:
        return mat
    settings.update(amount=float(amount), auto_touch=touch)
    scale = auto_touch(pbr).value * amount if touch else np.float32([amount])
    return scale_enhancement(mat, baseline(pbr), ParamMap(scale))


def baseline(pbr: PbrInputs) -> EnhancedMaterial:
    """The original PBR material expressed in the enhanced model, for comparisons.

    One GGX lobe with alpha = r^2 (haze weight 0), Gulbrandsen colour from the
    base colour where metallic, an IOR of 1.5 (F0 = 0.04) where not, no decorators.
    """
    rough = _clean(pbr.roughness, 0.0, 1.0, "roughness", pbr.name)
    values = {"spec_color": _clean(pbr.base_color, 0.0, 1.0, "base colour", pbr.name),
              "metalness": _clean(pbr.metalness, 0.0, 1.0, "metalness", pbr.name),
              "alpha_core": rough ** 2, "haze_weight": 0.0, "diel_ior": 1.5, "edge_tint": 1.0}
    params = {p.name: _fit(p.name, values.get(p.name, p.default)) for p in PARAMS}
    return EnhancedMaterial(pbr.name, -1, 0, ParamMap(values["spec_color"]), params,
                            {"type": "pbr baseline"})
