"""The base materials words name: material families, metals and finishes, with their PBR values.

One table for both directions: the generator's procedural corpus draws its objects' roughness from a
family's range and a metal's base colour from ``METALS`` (``torch_models/generator/procedural.py``),
and a prompt's words ("brushed gold metal", "red paint", "matte plastic") are read back into a base
colour, roughness and metalness (``prompt.read_prompt``) for a mesh that has no material, or whose
artist asks for the words' base instead of the mesh's.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class MaterialFamily:
    name: str
    words: tuple[str, ...]  # whole words that name it in a prompt
    roughness: tuple[float, float]  # the corpus's range; a prompt without a finish word gets its middle
    metal: bool = False

    @property
    def typical_roughness(self) -> float:
        return sum(self.roughness) / 2


FAMILIES: dict[str, MaterialFamily] = {f.name: f for f in (
    MaterialFamily("metal", ("metal", "metallic", "metals"), (0.1, 0.45), metal=True),
    MaterialFamily("paint", ("paint", "painted", "enamel", "car paint"), (0.05, 0.35)),
    MaterialFamily("plastic", ("plastic", "plastics", "rubber", "vinyl"), (0.3, 0.7)),
    MaterialFamily("ceramic", ("ceramic", "ceramics", "porcelain", "pottery", "tile", "tiles"), (0.03, 0.25)),
    MaterialFamily("wood", ("wood", "wooden", "timber", "oak", "pine", "walnut"), (0.45, 0.75)),
    MaterialFamily("fabric", ("fabric", "cloth", "textile", "cotton", "wool", "woollen", "linen", "denim"),
                   (0.8, 0.95)),
)}

# Linear base colour (F0) of each metal, metalness 1. The first six are the corpus's metals, in the
# order its draws index them; chrome is read from prompts only.
METALS: dict[str, tuple[float, float, float]] = {
    "silver": (0.91, 0.92, 0.92), "gold": (1.0, 0.77, 0.34), "copper": (0.95, 0.64, 0.54),
    "iron": (0.56, 0.57, 0.58), "aluminium": (0.91, 0.92, 0.92), "brass": (0.91, 0.78, 0.42),
    "chrome": (0.55, 0.56, 0.55),
}
CORPUS_METALS = ("silver", "gold", "copper", "iron", "aluminium", "brass")
METAL_SPELLINGS = {"aluminum": "aluminium", "steel": "iron", "chromium": "chrome", "golden": "gold",
                   "silvery": "silver", "coppery": "copper", "brassy": "brass"}

# Roughness a finish word asks for. "glossy"/"shiny" directly before a coat word describe the coat
# ("glossy clearcoat", as the captions write it), not the base.
FINISHES: dict[str, float] = {
    "mirror": 0.03, "polished": 0.08, "glossy": 0.15, "shiny": 0.15, "satin": 0.35, "brushed": 0.35,
    "semi gloss": 0.25, "rough": 0.7, "matte": 0.8, "matt": 0.8, "chalky": 0.9,
}
