"""The enhancement-type table: its two vocabularies are one, what derives from it adds up, and a type added
to it alone reaches every consumer."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from richmat_addon.core.captions import enhancement_keywords
from richmat_addon.core.enhance import enhance
from richmat_addon.core.enhancement_types import FAMILIES, METAL_TYPES, TYPE_MIX, TYPES, index_ranges
from richmat_addon.core.maps import ParamMap, PbrInputs
from richmat_addon.core.prompt import enhancements, prompt_type
from tests import toy_type

REPO = Path(__file__).resolve().parents[1]


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
    assert index_ranges(range(3)) == "0-2" and index_ranges([5, 4]) == "4-5" and index_ranges([0, 1, 2, 5]) == "0-2, 5"


def test_a_type_added_to_the_table_alone_reaches_enhancement_captions_the_farm_and_the_generator() -> None:
    """Type 6 (haze plus scattering, dielectric only) added as one row of ``TYPES`` (``tests/toy_type.py``)."""
    run = subprocess.run([sys.executable, "-c", "from tests import toy_type; toy_type.main()"], cwd=REPO,
                         env=dict(os.environ, PYTHONPATH=str(REPO)), capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    result = json.loads(next(ln for ln in run.stdout.splitlines() if ln.startswith("RESULT "))[len("RESULT "):])
    toy = toy_type.TOY
    assert result["types"] == [t.index for t in TYPES] + [toy]

    made = result["enhancement"]
    scatter = {d.key for d in FAMILIES["scatter"].draws}
    assert made["type"] == toy and scatter <= made["settings"].keys()
    assert not {"dust_peak", "fuzz_weight", "coat_ior"} & made["settings"].keys()
    assert made["params"]["inner_weight"] > 0 and made["params"]["coat_weight"] == 0 == made["params"]["dust_weight"]
    assert made["on_metal"][0] == 0 and "used type 0" in made["on_metal"][1]
    share = 0.1 / (sum(TYPE_MIX) + 0.1)  # the toy row's share of the mix, relative to the sum
    assert abs(made["auto_share"] - share) < 0.03

    words = result["words"]
    assert [w.split()[-1] for w in words["keywords"]] == ["haze", "scattering"]
    assert words["caption"].endswith("material with " + ", ".join(words["keywords"]))
    assert words["prompt"] == [toy, []] and words["caption_as_prompt"] == [toy, []]
    assert words["prompt_on_metal"][0] == 0 and "for dielectrics" in words["prompt_on_metal"][1][0]

    farm = result["farm"]
    assert abs(farm["planned_share"] - share) < 0.03 and farm["metal_material"][0] == 0
    assert farm["caption"].endswith(words["caption"].split(": ", 1)[1]) and farm["manifest_type"] == toy

    gen = result["generator"]
    assert gen["types"] == toy + 1 and gen["null_type"] == toy + 1 and gen["rows"] == toy + 2
    assert gen["unconditional"] == [toy + 1] and gen["sampled"][2] == 6 and gen["guidance"] == 1.25
    assert gen["shipped_types"] == len(TYPES) and "trained on enhancement types 0-5" in gen["shipped_refuses"]
