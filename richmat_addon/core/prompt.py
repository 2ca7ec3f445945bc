"""The enhancement type a prompt names, from the words batch captions use.

Captions carry "dust", "fuzz", "glossy clearcoat", "subsurface scattering" (with
strengths); a user's prompt may say "dusty", "coated", "velvet": both directions
are the families of ``enhancement_types``. The type is the one holding the most
named families, those only dielectric-only types have (fuzz, scattering) counted
first (fuzz takes the dust lobe's place, so "dusty velvet" is fuzz), then the one
adding the fewest lobes; on a metal a dielectric-only type falls back as the
enhancer does. Prompts naming none of them get Type 0, and the caller is told
that nothing was recognised (outside the training vocabulary). Pure Python in
``core``: the Blender add-on uplifts to the type the prompt names before the torch
backend generates the latents.
"""
from __future__ import annotations

import re

from .enhancement_types import DIELECTRIC_FAMILIES, FAMILIES, METAL_REMAP, TYPES, EnhancementType


def enhancements(prompt: str) -> set[str]:
    """The enhancement families a prompt names (whole words, case-insensitive)."""
    text = prompt.lower()
    return {family.name for family in FAMILIES.values()
            if any(re.search(rf"\b{re.escape(w)}\b", text) for w in family.prompt_words)}


def prompt_type(prompt: str, metallic: bool = False) -> tuple[int, list[str]]:
    """(type, warnings). Fuzz/scattering on a metal falls back as the enhancer does (4 -> 1, 5 -> 3)."""
    found = enhancements(prompt)
    warnings = [] if found else [f"no enhancement keyword in the prompt {prompt!r} "
                                 f"(known: {', '.join(sorted(FAMILIES))}); using Type 0 (haze)"]

    def rank(t: EnhancementType) -> tuple[int, int, int]:
        held = found & set(t.lobes)
        return len(held & DIELECTRIC_FAMILIES), len(held), -len(t.lobes)

    type_ = max(TYPES, key=rank).index
    if metallic and type_ in METAL_REMAP:
        dropped = [FAMILIES[f].noun for f in TYPES[type_].lobes if f not in TYPES[METAL_REMAP[type_]].lobes]
        type_ = METAL_REMAP[type_]
        warnings.append(f"{' and '.join(dropped)} are for dielectrics; ignored on a metal")
    return type_, warnings
