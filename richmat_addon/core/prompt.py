"""The enhancement type a prompt names, from the keywords batch captions use.

Captions carry "dust", "fuzz", "glossy clearcoat", "subsurface scattering" (with
strengths); a user's prompt may say "dusty", "coated", "velvet". The type is the
paper's: 0 haze only, 1 dust, 2 clearcoat, 3 dust + clearcoat, 4 fuzz/scattering,
5 fuzz/scattering + clearcoat. Prompts naming none of them get Type 0, and the
caller is told that nothing was recognised (outside the training vocabulary).
Pure Python in ``core``: the Blender add-on uplifts to the type the prompt names
before the torch backend generates the latents.
"""
from __future__ import annotations

import re

KEYWORDS: dict[str, tuple[str, ...]] = {
    "haze": ("haze", "hazy"),  # every type has haze: naming it alone is Type 0, and is understood
    "dust": ("dust", "dusty", "dirt", "dirty", "grime", "grimy"),
    "coat": ("clearcoat", "clear coat", "coat", "coated", "lacquer", "lacquered", "varnish", "varnished", "glaze",
             "glazed"),
    "fuzz": ("fuzz", "fuzzy", "velvet", "velvety", "felt", "peach fuzz", "lint"),
    "scatter": ("subsurface", "scattering", "translucent", "waxy", "wax", "skin"),
}


def enhancements(prompt: str) -> set[str]:
    """The enhancement families a prompt names (whole words, case-insensitive)."""
    text = prompt.lower()
    return {family for family, words in KEYWORDS.items()
            if any(re.search(rf"\b{re.escape(w)}\b", text) for w in words)}


def prompt_type(prompt: str, metallic: bool = False) -> tuple[int, list[str]]:
    """(type, warnings). Fuzz/scattering on a metal falls back as the enhancer does (4 -> 1, 5 -> 3)."""
    found = enhancements(prompt)
    warnings = [] if found else [f"no enhancement keyword in the prompt {prompt!r} "
                                 f"(known: {', '.join(sorted(KEYWORDS))}); using Type 0 (haze)"]
    soft = bool(found & {"fuzz", "scatter"})
    coat = "coat" in found
    if soft and not metallic:
        type_ = 5 if coat else 4
    else:
        if soft:
            warnings.append("fuzz and scattering are for dielectrics; ignored on a metal")
        type_ = {(False, False): 0, (True, False): 1, (False, True): 2, (True, True): 3}[("dust" in found or soft,
                                                                                           coat)]
    return type_, warnings
