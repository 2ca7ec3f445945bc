"""The enhancement-type table: its two vocabularies are one, and what derives from it adds up."""
from __future__ import annotations

import pytest

from richmat_addon.core.captions import enhancement_keywords
from richmat_addon.core.enhance import enhance
from richmat_addon.core.enhancement_types import FAMILIES, METAL_TYPES, TYPE_MIX, TYPES, index_ranges
from richmat_addon.core.maps import ParamMap, PbrInputs
from richmat_addon.core.prompt import enhancements, prompt_type


@pytest.mark.parametrize("family", FAMILIES.values(), ids=lambda f: f.name)
def test_a_caption_noun_reads_back_as_its_family(family) -> None:
    assert enhancements(family.noun) == {family.name}


@pytest.mark.parametrize("type_", [t.index for t in TYPES])
def test_a_caption_read_as_a_prompt_names_its_type(type_: int) -> None:
    pbr = PbrInputs("plastic", ParamMap.constant(0.6, 0.2, 0.2), ParamMap.constant(0.4), ParamMap.constant(0.0))
    words = ", ".join(enhancement_keywords(enhance(pbr, type_, seed=1).settings))
    assert prompt_type(f"a cup with {words}") == (type_, [])


def test_the_table_is_consistent() -> None:
    assert [t.index for t in TYPES] == list(range(len(TYPES)))
    assert sum(TYPE_MIX) == pytest.approx(1.0)
    assert all(t.metal_remap in METAL_TYPES for t in TYPES if t.dielectric_only)
    assert all(set(t.lobes) <= FAMILIES.keys() for t in TYPES)


def test_index_ranges_reads_like_prose() -> None:
    assert index_ranges(range(6)) == "0-5" and index_ranges([5, 4]) == "4-5" and index_ranges([0, 1, 2, 5]) == "0-2, 5"
