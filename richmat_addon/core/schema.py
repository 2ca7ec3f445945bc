"""The 22 parameters of the enhanced non-diffuse BRDF, as data.

This module is the single place where a parameter is named, typed, ranged and
explained. Every backend (torch evaluator, Cycles OSL builder, MaterialX
exporter, neural encoder) reads the list below instead of repeating it, and the
packed parameter vector used by the neural material follows ``PARAMS`` order.

Pure Python: importable inside a stock Blender (no numpy needed here).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

Kind = Literal["float", "color"]


@dataclass(frozen=True)
class Param:
    """One parameter of the non-diffuse component.

    ``lo``/``hi`` is the valid range (inputs are clamped to it); ``default`` is the
    value a disabled lobe or an un-enhanced material uses.
    """

    name: str
    lobe: str
    kind: Kind
    lo: float
    hi: float
    default: float | tuple[float, float, float]
    doc: str

    @property
    def channels(self) -> int:
        return 3 if self.kind == "color" else 1


# Numerical floor for GGX alpha: Cycles treats alpha_x * alpha_y <= 2e-10 as a
# singular (delta) lobe that light samples cannot evaluate. 1e-4 squared is 1e-8.
ALPHA_MIN = 1e-4
# Cycles clamps sheen roughness to [1e-3, 1] (bsdf_sheen.h).
SHEEN_ROUGHNESS_MIN = 1e-3

PARAMS: tuple[Param, ...] = (
    # Lobe 1: dust / fuzz (sheen on top of everything).
    Param("dust_weight", "dust", "float", 0.0, 1.0, 0.0,
          "Coverage of the dust/fuzz sheen layer; 0 disables the lobe."),
    Param("dust_roughness", "dust", "float", SHEEN_ROUGHNESS_MIN, 1.0, 0.5,
          "Sheen roughness ('thickness'): low values only show at grazing angles."),
    # Lobe 2: clearcoat.
    Param("coat_weight", "coat", "float", 0.0, 1.0, 0.0,
          "Clearcoat presence, binary in the enhancement (a damage mask may cut holes)."),
    Param("coat_ior", "coat", "float", 1.3, 1.8, 1.5,
          "Refractive index of the coat (lacquer, glaze, resin)."),
    Param("coat_alpha", "coat", "float", ALPHA_MIN, 1.0, 0.01,
          "GGX alpha of the coat: low, a sharp glossy highlight."),
    # Lobes 3/4: conductor core and haze.
    Param("spec_color", "conductor", "color", 0.0, 0.99, (0.9, 0.9, 0.9),
          "Conductor reflectivity at normal incidence (Gulbrandsen r); the PBR base colour."),
    Param("edge_tint", "conductor", "float", 0.0, 1.0, 1.0,
          "Gulbrandsen edge tint g (grey): 1 gives a Schlick-like metal, lower values a grazing dip."),
    Param("metalness", "mix", "float", 0.0, 1.0, 0.0,
          "Mix between the dielectric branch (0) and the conductor branch (1)."),
    # Shared by both branches' core and haze lobes.
    Param("alpha_core", "specular", "float", ALPHA_MIN, 1.0, 0.25,
          "GGX alpha of the core lobes: r**p with p > 2."),
    Param("alpha_haze", "specular", "float", ALPHA_MIN, 1.0, 0.5,
          "GGX alpha of the haze lobes: min(1, s * r**q) with q < 2, s > 1."),
    Param("haze_weight", "specular", "float", 0.0, 1.0, 0.0,
          "Share of the specular energy in the haze lobe; the core gets 1 - haze_weight."),
    # Lobes 5/6: dielectric core and haze.
    Param("diel_ior", "dielectric", "float", 1.3, 1.8, 1.5,
          "Refractive index of the dielectric core and haze lobes."),
    # Lobe 7: inner scattering (sheen under the dielectric lobes).
    Param("inner_weight", "inner", "float", 0.0, 1.0, 0.0,
          "Strength of the inner-scattering sheen; 0 disables the lobe."),
    Param("inner_roughness", "inner", "float", SHEEN_ROUGHNESS_MIN, 1.0, 0.5,
          "Sheen roughness of the inner-scattering layer."),
    Param("scatter_color", "inner", "color", 0.0, 1.0, (1.0, 1.0, 1.0),
          "Tint of lobes 7 and 8: a gentle desaturation of the base colour."),
    # Lobe 8: subcutaneous scattering (rough tinted GGX under lobe 7).
    Param("subsurf_weight", "subsurf", "float", 0.0, 1.0, 0.0,
          "Presence of the subcutaneous lobe, binary in the enhancement."),
    Param("subsurf_alpha", "subsurf", "float", ALPHA_MIN, 1.0, 0.6,
          "GGX alpha of the subcutaneous lobe: high."),
    Param("subsurf_ior", "subsurf", "float", 1.3, 1.8, 1.4,
          "Fresnel index of the subcutaneous lobe."),
)

PARAM_BY_NAME: dict[str, Param] = {p.name: p for p in PARAMS}
N_CHANNELS: int = sum(p.channels for p in PARAMS)
assert N_CHANNELS == 22, N_CHANNELS


def channel_slices() -> dict[str, slice]:
    """Where each parameter lives in the packed 22-channel vector."""
    out: dict[str, slice] = {}
    start = 0
    for p in PARAMS:
        out[p.name] = slice(start, start + p.channels)
        start += p.channels
    return out


CHANNEL_SLICES: dict[str, slice] = channel_slices()


def default_vector() -> list[float]:
    """The packed vector of an un-enhanced (all decorators off) material."""
    vec: list[float] = []
    for p in PARAMS:
        vec.extend(p.default if isinstance(p.default, tuple) else (p.default,))
    return vec


def bounds() -> tuple[list[float], list[float]]:
    """Per-channel lower and upper bounds of the packed vector."""
    lo: list[float] = []
    hi: list[float] = []
    for p in PARAMS:
        lo.extend([p.lo] * p.channels)
        hi.extend([p.hi] * p.channels)
    return lo, hi
