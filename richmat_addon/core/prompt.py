"""What a prompt names: the enhancement type and its strengths, and the base material (colour, family, finish).

Captions carry "dust", "fuzz", "glossy clearcoat", "subsurface scattering" (with
strengths); a user's prompt may say "dusty", "coated", "velvet": both directions
are the families of ``enhancement_types``. The type is the one holding the most
named families, those only dielectric-only types have (fuzz, scattering) counted
first (fuzz takes the dust lobe's place, so "dusty velvet" is fuzz), then the one
adding the fewest lobes; on a metal a dielectric-only type falls back as the
enhancer does. Prompts naming none of them get Type 0, and the caller is told
that nothing was recognised (outside the training vocabulary).

``read_prompt`` reads the rest the way captions write it, so a caption read back gives
its material: a strength word before a family's word ("light dust", "a little dust",
"caked in dust": ``captions.STRENGTH_SYNONYMS``) fixes the setting the caption worded to
the middle of that word's third of its range (``captions.strength_value``); a colour name
of the named-colour table, longest first, with a modifier ("dark", "pale") the table lacks
applied in CIELAB; a material family, metal and finish (``base_materials``) give metalness
and roughness. ``base_over`` puts that base on a material where it has no texture or the
artist asks for it. numpy only, in ``core``: the Blender add-on shows what it read and
uplifts with it before the torch backend generates the latents.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from . import base_materials, named_colours
from .captions import STRENGTH_SYNONYMS, strength_value
from .colour import lab_to_linear, linear_to_lab, linear_to_srgb
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


# CIELAB change of a modifier the table has no compound for ("dark teal"): (lightness scale, share of the
# way to white, chroma scale).
MODIFIERS: dict[str, tuple[float, float, float]] = {
    "dark": (0.6, 0.0, 1.0), "deep": (0.7, 0.0, 1.15), "light": (1.0, 0.45, 0.75), "pale": (1.0, 0.5, 0.5),
    "pastel": (1.0, 0.55, 0.45), "bright": (1.05, 0.0, 1.25), "vivid": (1.0, 0.0, 1.3), "dull": (0.95, 0.0, 0.6),
    "muted": (1.0, 0.0, 0.6), "dusky": (0.8, 0.0, 0.8),
}
# Words that may stand between a strength word and its family's ("thick layer of dust", "caked in dust").
_FILLER = frozenset(("of", "in", "with", "a", "an", "layer", "layers", "film", "coating", "covering", "bit"))
_COAT_WORDS = frozenset(w for w in FAMILIES["coat"].prompt_words if " " not in w) | {"clear"}
_LONGEST_NAME = 4  # words


@dataclass(frozen=True)
class Reading:
    """What a prompt names. ``colour`` is linear sRGB; None where the words do not say."""

    prompt: str
    type: int
    warnings: list[str]
    strengths: dict[str, str] = field(default_factory=dict)  # enhancement family -> "light"/"moderate"/"heavy"
    colour_name: str | None = None  # as read, with its modifier ("dark teal")
    colour: tuple[float, float, float] | None = None
    family: str | None = None  # a ``base_materials.FAMILIES`` name
    metal: str | None = None  # a ``base_materials.METALS`` name
    finish: str | None = None  # a ``base_materials.FINISHES`` word
    unread_colour: str | None = None  # no colour read, and this unknown word stands before the material's word

    @property
    def metalness(self) -> float | None:
        return None if self.family is None else float(base_materials.FAMILIES[self.family].metal)

    @property
    def roughness(self) -> float | None:
        if self.finish is not None:
            return base_materials.FINISHES[self.finish]
        return None if self.family is None else base_materials.FAMILIES[self.family].typical_roughness

    def settings(self) -> dict[str, float]:
        """The enhancement settings the strength words fix (``enhance``'s ``fixed``)."""
        out = {}
        for name, word in self.strengths.items():
            lo, hi = FAMILIES[name].drawn
            out[FAMILIES[name].setting] = strength_value(word, lo, hi)
        return out

    def lines(self) -> list[str]:
        """What was read, a line per thing, as the add-on's panel and the CLI show it."""
        t = TYPES[self.type]
        strengths = ", ".join(f"{w} {FAMILIES[f].noun}" for f, w in self.strengths.items())
        lines = [f"Type {t.index} ({t.label})" + (f": {strengths}" if strengths else "")]
        if self.colour_name is not None:
            srgb = "".join(f"{round(float(v) * 255):02x}" for v in linear_to_srgb(self.colour))
            lines.append(f"colour: {self.colour_name} (#{srgb})")
        elif self.unread_colour is not None:
            lines.append(f"colour: {self.unread_colour!r} is not a colour name the table knows "
                         "(the backend tries the nearest by meaning)")
        if self.family is not None or self.finish is not None:
            what = " ".join(w for w in (self.finish, self.metal or self.family) if w)
            lines.append(f"material: {what}, metalness {self.metalness or 0:g}, roughness {self.roughness:.2f}")
        return lines

    def record(self) -> dict:
        return {"type": self.type, "strengths": self.strengths, "settings": self.settings(),
                "colour_name": self.colour_name, "colour": None if self.colour is None else list(self.colour),
                "family": self.family, "metal": self.metal, "finish": self.finish, "metalness": self.metalness,
                "roughness": self.roughness, "unread_colour": self.unread_colour}


def _tokens(prompt: str) -> list[str]:
    words = re.findall(r"[a-z0-9']+|[,;.]", prompt.lower().replace("-", " ").replace("/", " "))
    return ["grey" if w == "gray" else w for w in words]  # the table spells the survey's grey


def _phrase_at(tokens: list[str], i: int, phrases) -> str | None:
    """The longest of ``phrases`` (space-separated words) that starts at token ``i``."""
    for n in range(_LONGEST_NAME, 0, -1):
        phrase = " ".join(tokens[i:i + n])
        if i + n <= len(tokens) and phrase in phrases:
            return phrase
    return None


def _family_words() -> dict[str, str]:
    """Enhancement word -> family name."""
    return {w: f.name for f in FAMILIES.values() for w in f.prompt_words}


def _strengths(tokens: list[str]) -> dict[str, str]:
    """Family -> strength word, for each worded family named with a strength word before it."""
    words = _family_words()
    synonyms = {p: word for word, phrases in STRENGTH_SYNONYMS.items() for p in phrases}
    found: dict[str, str] = {}
    for j in range(len(tokens)):
        family = words.get(tokens[j]) or words.get(" ".join(tokens[j:j + 2]))
        if family is None or FAMILIES[family].drawn is None or family in found:
            continue
        k = j
        while k > 0 and tokens[k - 1] in _FILLER and j - k < 3:
            k -= 1
        for start in range(max(0, k - 3), k):  # a phrase of up to three words ending just before k
            phrase = " ".join(tokens[start:k])
            if phrase in synonyms:
                found[family] = synonyms[phrase]
                break
    return found


def _colour(tokens: list[str], skip: set[str]) -> tuple[str, np.ndarray] | None:
    """The first colour name of the table in the prompt (longest match), with a modifier before it that
    the table has no compound for; names that are another word of the vocabulary (``skip``) are not colours,
    nor is a colour directly before a word for dust ("white dust")."""
    table = named_colours.table()
    enhancement = _family_words()
    for i in range(len(tokens)):
        name = _phrase_at(tokens, i, table)
        if name is None or name in skip:
            continue
        after = i + len(name.split())
        if after < len(tokens) and enhancement.get(tokens[after]) == "dust":
            continue
        colour = np.asarray(table[name], np.float64)
        modifier = tokens[i - 1] if i > 0 and tokens[i - 1] in MODIFIERS else None
        if modifier is None:
            return name, colour
        scale, whiten, chroma = MODIFIERS[modifier]
        lab = linear_to_lab(colour)
        lightness = lab[0] * scale + (100 - lab[0] * scale) * whiten
        return f"{modifier} {name}", np.clip(lab_to_linear([lightness, lab[1] * chroma, lab[2] * chroma]), 0, 1)
    return None


def read_prompt(prompt: str, metallic: bool | None = None) -> Reading:
    """Everything a prompt names (module docstring). ``metallic``: whether the material the type goes on is a
    metal (the type then keeps off dielectric-only lobes); None: a metal where the words name one."""
    tokens = _tokens(prompt)
    family_words = {w: f.name for f in base_materials.FAMILIES.values() for w in f.words}
    metal_words = {**{m: m for m in base_materials.METALS}, **base_materials.METAL_SPELLINGS}
    family = next((family_words[p] for i in range(len(tokens))
                   if (p := _phrase_at(tokens, i, family_words)) is not None), None)
    metal = next((metal_words[t] for t in tokens if t in metal_words), None)
    if metal is not None and family in (None, "metal"):
        family = "metal"
    else:
        metal = None  # "gold paint": the metal's name is a colour
    finish = None
    for i in range(len(tokens)):
        word = _phrase_at(tokens, i, base_materials.FINISHES)
        if word is not None and not (word in ("glossy", "shiny") and i + 1 < len(tokens)
                                     and tokens[i + 1] in _COAT_WORDS):
            finish = word
            break
    skip = set(_family_words()) | set(family_words) | set(base_materials.FINISHES) | set(MODIFIERS)
    if metal is not None:
        skip |= {w for w, m in metal_words.items() if m == metal}  # "gold metal": the metal's own colour
    found = _colour(tokens, skip)
    colour_name, colour = found if found else (metal, np.asarray(base_materials.METALS[metal])) if metal \
        else (None, None)
    type_, warnings = prompt_type(prompt, family == "metal" if metallic is None else metallic)
    unread = None if colour is not None else _unread_colour(tokens, set(family_words) | set(metal_words), skip)
    return Reading(prompt, type_, warnings, _strengths(tokens), colour_name,
                   None if colour is None else tuple(float(c) for c in colour), family, metal, finish, unread)


_NOT_COLOURS = frozenset(("a", "an", "the", "my", "some", "old", "new", "with", "and", "of", "on", "in", "for"))


def _unread_colour(tokens: list[str], material_words: set[str], known: set[str]) -> str | None:
    """The word just before the first material word ("vermilion paint") when no vocabulary knows it."""
    synonyms = {w for phrases in STRENGTH_SYNONYMS.values() for p in phrases for w in p.split()}
    for i, token in enumerate(tokens[1:], 1):
        if token in material_words:
            word = tokens[i - 1]
            unknown = word.isalpha() and word not in known | synonyms | _NOT_COLOURS | set(base_materials.FINISHES)
            return word if unknown else None
    return None


def keeps_base(base_color: np.ndarray, choice: str) -> bool:
    """Whether a material keeps its own base colour: ``choice`` "mesh" or "words", or "auto": keep it where
    it is a texture (a painted asset), take the words' where it is one colour (a bare mesh, a default
    material)."""
    if choice not in ("auto", "mesh", "words"):
        raise ValueError(f"base colour choice {choice!r}: use auto, mesh or words")
    return choice == "mesh" or choice == "auto" and np.asarray(base_color).size > 3


def base_over(reading: Reading, base_color: np.ndarray, roughness: np.ndarray | None,
              metalness: np.ndarray | None, keep: bool) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """A material's (base colour, roughness, metalness) with the words' put on: the named colour unless it
    ``keep``s its own, the family's metalness and the finish's (or family's) roughness where the words name
    them and the material does not say (None), or does not ``keep`` its own. Constants come back (1, 1, C)."""
    def constant(value) -> np.ndarray:
        return np.asarray(value, np.float32).reshape(1, 1, -1)

    if reading.colour is not None and not keep:
        base_color = constant(reading.colour)
    if reading.roughness is not None and (roughness is None or not keep):
        roughness = constant(reading.roughness)
    if reading.metalness is not None and (metalness is None or not keep):
        metalness = constant(reading.metalness)
    if roughness is not None and metalness is None:  # a finish without a family: a dielectric, as unknown maps are
        metalness = constant(0.0)
    return base_color, roughness, metalness
