"""A caption per asset from what is known, without a captioning model or the network.

Asset name, material names, the colour of each material's mean base colour,
metal or not, plus the enhancement keywords with their strength ("light dust",
"scratched glossy clearcoat"), as the paper augments its captions with the
enhancement type. Its words are the families of ``enhancement_types``, the table
prompts are read with (``prompt``). In core because batch captions its renders and
the generator's procedural corpus (torch_models) captions its objects alike.
"""
from __future__ import annotations

import colorsys
import re
from typing import Any, Sequence

from .colour import linear_to_gamma
from .enhancement_types import BASE_FAMILY, FAMILIES

# Hue names by upper bound of the hue angle in degrees.
_HUES = ((15, "red"), (45, "orange"), (70, "yellow"), (160, "green"), (200, "cyan"),
         (260, "blue"), (300, "purple"), (345, "pink"), (360, "red"))



def colour_name(linear_rgb: Sequence[float]) -> str:
    """A plain colour word for a linear RGB base colour.

    Encoded with the corpus's 1/2.2 power (``colour.linear_to_gamma``) rather than the exact sRGB curve: the exact curve renames the colour of 37
    of the first 1200 procedural corpus objects (mostly wood, brown to orange), and the shipped generator
    learned, and the benches prompt it with, the captions this one writes."""
    srgb = [linear_to_gamma(c) for c in linear_rgb]
    h, s, v = colorsys.rgb_to_hsv(*srgb)
    if v < 0.15:
        return "black"
    if s < 0.15:
        return "white" if v > 0.85 else "light grey" if v > 0.6 else "grey" if v > 0.35 else "dark grey"
    hue = next(name for bound, name in _HUES if h * 360 <= bound)
    if hue == "orange" and v < 0.6:
        hue = "brown"
    return ("dark " if v < 0.45 else "pale " if s < 0.35 else "") + hue


STRENGTHS = ("light", "moderate", "heavy")  # a worded setting's thirds of its drawn range, in order
# What else a prompt may say for each strength word (whole words or phrases, before the family's word).
STRENGTH_SYNONYMS: dict[str, tuple[str, ...]] = {
    "light": ("light", "lightly", "a little", "a bit of", "a touch of", "a hint of", "slight", "slightly", "faint",
              "faintly", "thin", "subtle", "soft", "barely", "traces of"),
    "moderate": ("moderate", "moderately", "medium", "some", "fair", "noticeable"),
    "heavy": ("heavy", "heavily", "thick", "thickly", "caked", "lots of", "a lot of", "much", "strong", "strongly",
              "dense", "deep", "very", "covered", "layers of", "plenty of"),
}


def _strength(value: float, lo: float, hi: float) -> str:
    t = (value - lo) / (hi - lo) if hi > lo else 0.5
    return STRENGTHS[min(int(t * len(STRENGTHS)), len(STRENGTHS) - 1)] if t >= 0 else STRENGTHS[0]


def strength_value(word: str, lo: float, hi: float) -> float:
    """The setting a strength word stands for: the middle of its third of [lo, hi], the caption's word
    read back (``_strength(strength_value(w, lo, hi), lo, hi) == w``)."""
    return lo + (hi - lo) * (STRENGTHS.index(word) + 0.5) / len(STRENGTHS)


def enhancement_keywords(settings: dict[str, Any]) -> list[str]:
    """Keywords of one material's enhancement settings (``params.json``'s ``settings``): each family
    applied (the base family always), in ``FAMILIES`` order, with its strength or damage."""
    words = []
    for family in FAMILIES.values():
        if family.setting not in settings and family.name != BASE_FAMILY:
            continue
        prefix = ""
        if family.drawn is not None:
            lo, hi = family.drawn
            prefix = _strength(settings.get(family.setting, (lo + hi) / 2), lo, hi) + " "
        if family.damage is not None:
            key, adjectives = family.damage
            damage = settings.get(key, "none")
            prefix += "" if damage == "none" else adjectives.get(damage, damage) + " "
        words.append(prefix + family.noun)
    return words


def readable(name: str) -> str:
    """``WaterBottle_v2.001`` -> ``water bottle v2``."""
    text = re.sub(r"\.\d{3}$", "", name)
    text = re.sub(r"(?<=[a-z])(?=[A-Z])", " ", text)
    text = re.sub(r"[-_.]+|\s+", " ", text).strip().lower()
    return re.sub(r"\b[0-9a-f]{10}$", "", text).strip() or "object"


# Words spelt with a vowel that start with a consonant sound ("a unicorn", "a one-off"), and the reverse.
_CONSONANT_SOUND = ("uni", "use", "usu", "uti", "ura", "ure", "uro", "ute", "usb", "uav", "ufo", "ubiq", "eu", "ewe",
                    "one", "once")
_VOWEL_SOUND = ("hour", "honest", "honor", "honour", "heir")
_VOWEL_LETTER_NAMES = frozenset("aefhilmnorsx")  # letters whose spoken name starts with a vowel: "an fbx"


def article(word: str) -> str:
    """The article by how ``word`` is spoken: "an evo", "a unicorn", "an hour", "an 8", "an fbx" (a word
    without vowels is read as letters)."""
    w = word.lower()
    if not w:
        return "a"
    if w[0].isdigit():
        number = re.match(r"\d+", w).group()  # "an 8", "an 80", "an 11", "an 18000"; "a 110"
        return "an" if number[0] == "8" or len(number) % 3 == 2 and number.startswith(("11", "18")) else "a"
    if not re.search(r"[aeiouy]", w) and w.isalpha():
        return "an" if w[0] in _VOWEL_LETTER_NAMES else "a"
    if w.startswith(_VOWEL_SOUND):
        return "an"
    return "an" if w[0] in "aeiou" and not w.startswith(_CONSONANT_SOUND) else "a"


def caption(asset_name: str, materials: Sequence[dict[str, Any]]) -> str:
    """One sentence: the object, then each material with colour, kind and enhancements."""
    parts = []
    for m in materials:
        kind = "metal" if m["metallic"] else "material"
        words = ", ".join(enhancement_keywords(m["settings"]))
        colour, name = colour_name(m["mean_base_color"]), readable(m["name"])
        described = name if colour.split()[-1] in name.split() else f"{colour} {name}"
        if described.split()[-1] != kind:  # "body material", not "body material material"
            described += f" {kind}"
        parts.append(f"{described} with {words}")
    body = "; ".join(parts) if parts else "no materials"
    name = readable(asset_name)
    return f"{article(name.split()[0])} {name}: {body}"
