"""The enhancement types (paper sec. 3.2) and the words for them: the one table.

A type is the set of lobe families the enhancement adds on top of the core and
haze lobes every material gets, its share of the paper's dataset mix, for a
type made for dielectrics the type a metal gets instead, and the guidance the
generator samples it with. A family carries both directions of the vocabulary:
the words a prompt may name it by (``prompt.prompt_type``) and the words a
caption describes it with (``captions.enhancement_keywords``), and the settings
``enhance`` draws when it applies the family, with their ranges (the caption's
strength word reads one of them). Everything else that speaks of types (the
CLI's choices, the add-on's menu, batch's plan, the dust types that need world
maps, the decoder's training classes, the generator's type tokens, the benches'
loops) reads it here; a trained generator keeps the type count it was trained
with (``generator.dit.DitConfig.types``).

Adding a type or a family means editing:
- this file: a row in ``TYPES`` (and a ``Family`` in ``FAMILIES`` for a new lobe);
- ``core/enhance.py``, the numpy backend: the parameter values of a new lobe;
- ``torch_models/neural/data.py``, the torch backend, only for a new family: its
  themed class of decoder training vectors (``CLASSES`` is derived, the mask
  variation of a new lobe is not).
A new type built from existing families needs this file alone, and a generator
trained after it (an older checkpoint refuses the new type).
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass


@dataclass(frozen=True)
class Draw:
    """A setting ``enhance`` draws uniformly from [lo, hi] per material."""

    key: str
    lo: float
    hi: float


@dataclass(frozen=True)
class Family:
    """One kind of lobe, as ``enhance`` applies it and as prompts and captions name it."""

    name: str
    prompt_words: tuple[str, ...]  # whole words (any case) that name it in a prompt
    noun: str  # what a caption calls it, after its strength word
    setting: str  # the settings key ``enhance`` writes when it applies the family
    # What ``enhance`` draws when it applies the family, in the order it draws them: the order is the
    # random stream's, so reordering changes every material made from a seed.
    draws: tuple[Draw, ...] = ()
    worded: bool = True  # the caption words the draw of ``setting`` light/moderate/heavy
    damage: tuple[str, dict[str, str]] | None = None  # settings key of a damage mask, and its adjectives

    @property
    def drawn(self) -> tuple[float, float] | None:
        """The range the caption's strength word reads ``setting`` against; None when it is not worded."""
        if not self.worded:
            return None
        draw = next(d for d in self.draws if d.key == self.setting)
        return draw.lo, draw.hi


@dataclass(frozen=True)
class EnhancementType:
    index: int
    label: str
    description: str
    lobes: tuple[str, ...]  # family names beyond the base family, in the order ``enhance`` draws them
    mix: float  # share in the paper's dataset
    # Classifier-free guidance the generator samples this type with by default: per type, the best mean PSNR
    # of 1, 1.5, 2 and 2.5 on its held-out procedural objects with the shipped generator 3b7998e4
    # (bench/generator/generate_guidance.py, docs/reports/generate_guidance.json). Type 4's captions are met by the
    # prompted model alone: more guidance overshoots them. Guidance 1 also skips the unconditional pass.
    guidance: float
    metal_remap: int | None = None  # set for a dielectric-only type: the type a metal gets instead

    @property
    def dielectric_only(self) -> bool:
        return self.metal_remap is not None


BASE_FAMILY = "haze"  # on every type, so no type lists it
# In caption order. The base family also draws the core lobe's settings (p: core sharpness, q and s: haze
# width, the dielectric IOR, the edge tint): every material gets both lobes.
FAMILIES: dict[str, Family] = {f.name: f for f in (
    # every type has haze: naming it alone is Type 0, and is understood
    Family("haze", ("haze", "hazy"), "haze", "haze_weight",
           (Draw("p", 2.2, 3.5), Draw("q", 1.2, 1.8), Draw("s", 1.1, 1.6), Draw("haze_weight", 0.1, 0.4),
            Draw("diel_ior", 1.4, 1.7), Draw("edge_tint", 0.85, 1.0))),
    Family("dust", ("dust", "dusty", "dirt", "dirty", "grime", "grimy"), "dust", "dust_peak",
           (Draw("dust_peak", 0.3, 0.9), Draw("dust_roughness", 0.3, 0.8))),
    Family("fuzz", ("fuzz", "fuzzy", "velvet", "velvety", "felt", "peach fuzz", "lint"), "fuzz", "fuzz_weight",
           (Draw("fuzz_weight", 0.2, 0.7), Draw("fuzz_roughness", 0.3, 0.8))),
    Family("coat", ("clearcoat", "clear coat", "coat", "coated", "lacquer", "lacquered", "varnish", "varnished",
                    "glaze", "glazed"), "glossy clearcoat", "coat_ior",
           (Draw("coat_ior", 1.45, 1.6), Draw("coat_alpha", 0.0025, 0.02)), worded=False,
           damage=("coat_damage", {"scratches": "scratched", "dents": "dented"})),
    Family("scatter", ("subsurface", "scattering", "translucent", "waxy", "wax", "skin"), "subsurface scattering",
           "inner_weight", (Draw("inner_weight", 0.2, 0.6), Draw("inner_roughness", 0.3, 0.7),
                            Draw("subsurf_alpha", 0.5, 0.9), Draw("subsurf_ior", 1.3, 1.5))),
)}

TYPES: tuple[EnhancementType, ...] = (
    EnhancementType(0, "Haze", "Haze: core + haze highlights on every material", (), 0.1, guidance=2.5),
    EnhancementType(1, "Dust", "Dust: haze plus dust on upward-facing surfaces", ("dust",), 0.2, guidance=2.0),
    EnhancementType(2, "Clearcoat", "Clearcoat: haze plus a glossy coat, sometimes damaged", ("coat",), 0.2,
                    guidance=2.5),
    EnhancementType(3, "Dust + clearcoat", "Dust + clearcoat", ("dust", "coat"), 0.2, guidance=2.0),
    EnhancementType(4, "Fuzz + inner and subcutaneous scattering",
                    "Fuzz + inner and subcutaneous scattering (dielectrics only)", ("fuzz", "scatter"), 0.1,
                    guidance=1.0, metal_remap=1),
    EnhancementType(5, "Fuzz + clearcoat + inner and subcutaneous scattering",
                    "Fuzz + clearcoat + inner and subcutaneous scattering (dielectrics only)",
                    ("fuzz", "coat", "scatter"), 0.2, guidance=1.5, metal_remap=3),
)


def types_with(family: str) -> tuple[int, ...]:
    """The types that apply ``family``, in index order."""
    return tuple(t.index for t in TYPES if family in t.lobes)


def index_ranges(indices: Iterable[int]) -> str:
    """Type indices as a reader writes them: ``0-3``, ``4-5``, ``0-2, 5``."""
    runs: list[list[int]] = []
    for i in sorted(indices):
        if runs and i == runs[-1][-1] + 1:
            runs[-1].append(i)
        else:
            runs.append([i])
    return ", ".join(f"{r[0]}-{r[-1]}" if len(r) > 1 else str(r[0]) for r in runs)


TYPE_MIX: tuple[float, ...] = tuple(t.mix for t in TYPES)
DIELECTRIC_ONLY: tuple[int, ...] = tuple(t.index for t in TYPES if t.dielectric_only)
METAL_TYPES: tuple[int, ...] = tuple(t.index for t in TYPES if not t.dielectric_only)
# What a dielectric-only type becomes on a metal: drop the scattering, keep the rest.
METAL_REMAP: dict[int, int] = {t.index: t.metal_remap for t in TYPES if t.metal_remap is not None}
DUST_TYPES = frozenset(types_with("dust"))  # the types whose dust follows world normals
# Families no metal type has: a prompt naming one asks for a dielectric-only type.
DIELECTRIC_FAMILIES = frozenset(f for t in TYPES if t.dielectric_only for f in t.lobes) - \
    {f for t in TYPES if not t.dielectric_only for f in t.lobes}
