"""Reading a prompt's words: colour names and modifiers, metals, finishes, strengths; CIEDE2000."""
from pathlib import Path

import numpy as np
import pytest

from richmat_addon.core import named_colours
from richmat_addon.core.base_materials import FINISHES, METALS
from richmat_addon.core.captions import STRENGTH_SYNONYMS, STRENGTHS, _strength, enhancement_keywords
from richmat_addon.core.colour import ciede2000, lab_to_linear, linear_to_lab, srgb_to_linear
from richmat_addon.core.enhance import enhance
from richmat_addon.core.enhancement_types import FAMILIES
from richmat_addon.core.maps import ParamMap, PbrInputs
from richmat_addon.core.prompt import base_over, keeps_base, read_prompt

SHARMA = Path(__file__).parent / "data" / "ciede2000_sharma2005.tsv"


def test_ciede2000_gives_the_published_differences_of_sharmas_34_pairs():
    pairs = np.loadtxt(SHARMA)
    assert pairs.shape == (34, 7)
    assert np.abs(ciede2000(pairs[:, :3], pairs[:, 3:6]) - pairs[:, 6]).max() < 1e-4
    assert np.abs(ciede2000(pairs[:, 3:6], pairs[:, :3]) - pairs[:, 6]).max() < 1e-4  # symmetric


def test_cielab_of_white_and_grey_and_back():
    assert np.allclose(linear_to_lab([1.0, 1.0, 1.0]), [100, 0, 0], atol=1e-4)
    assert linear_to_lab([0.18, 0.18, 0.18])[0] == pytest.approx(49.5, abs=0.1)  # middle grey is L* 50
    rgb = np.array([[0.2, 0.5, 0.1], [0.9, 0.05, 0.3]])
    assert np.allclose(lab_to_linear(linear_to_lab(rgb)), rgb, atol=1e-9)


def test_the_named_colour_file_is_matplotlibs_table():
    assert named_colours.from_matplotlib() == __import__("json").loads(named_colours.TABLE.read_text())["colours"]
    assert len(named_colours.table()) > 1000


def de(reading, srgb_hex: str) -> float:
    want = srgb_to_linear(np.array([int(srgb_hex[i:i + 2], 16) for i in (0, 2, 4)]) / 255)
    return float(ciede2000(linear_to_lab(reading.colour), linear_to_lab(want)))


@pytest.mark.parametrize("prompt, name, hex_", [
    ("red paint with light dust", "red", "e50000"),  # the XKCD survey's red
    ("a dark red plastic cup", "dark red", "840000"),  # compounds the table holds win over the modifier
    ("pale blue ceramic", "pale blue", "d0fefe"),
    ("off-white paint", "off white", "ffffe4"),
    ("Firebrick Lacquer", "firebrick", "b22222"),  # a CSS4 name the survey lacks
    ("dark gray plastic", "dark grey", "363737"),  # either spelling
    ("navy blue fabric with fuzz", "navy blue", "001146"),
])
def test_colour_names_are_read_from_the_table(prompt, name, hex_):
    r = read_prompt(prompt)
    assert r.colour_name == name and de(r, hex_) < 0.5


def test_a_modifier_the_table_lacks_moves_the_colour_in_cielab():
    teal = linear_to_lab(read_prompt("teal paint").colour)
    dark, pale = (linear_to_lab(read_prompt(f"{m} teal paint").colour) for m in ("dusky", "pastel"))
    assert read_prompt("dusky teal paint").colour_name == "dusky teal"
    assert dark[0] < teal[0] - 5 and pale[0] > teal[0] + 5
    assert np.hypot(*pale[1:]) < np.hypot(*teal[1:]) / 2  # pastel: less chroma


def test_words_for_dust_are_not_colours_and_white_dust_is_not_the_base():
    r = read_prompt("blue paint with white dust")
    assert r.colour_name == "blue" and r.type == 1
    assert read_prompt("paint with heavy dust").colour is None  # "dust" is an XKCD colour, but here it is dust


@pytest.mark.parametrize("word, metal", [("gold", "gold"), ("copper", "copper"), ("brass", "brass"),
                                         ("silver", "silver"), ("aluminium", "aluminium"), ("aluminum", "aluminium"),
                                         ("iron", "iron"), ("steel", "iron"), ("chrome", "chrome")])
def test_metals_read_as_metalness_one_with_the_metals_colour(word, metal):
    r = read_prompt(f"brushed {word} with a glossy clearcoat")
    assert (r.family, r.metal, r.metalness) == ("metal", metal, 1.0)
    assert r.colour == pytest.approx(METALS[metal], abs=1e-6)
    assert r.finish == "brushed" and r.roughness == FINISHES["brushed"]  # "glossy" is the coat's
    assert r.type == 2


def test_a_metals_name_on_another_family_is_a_colour_and_a_named_colour_tints_a_metal():
    gold_paint = read_prompt("gold paint")
    assert gold_paint.family == "paint" and gold_paint.metalness == 0.0 and gold_paint.colour_name == "gold"
    red_metal = read_prompt("red anodised aluminium")
    assert red_metal.metalness == 1.0 and red_metal.colour_name == "red"


@pytest.mark.parametrize("prompt, roughness", [("polished marble ceramic", 0.08), ("matte black plastic", 0.8),
                                               ("rough wooden table", 0.7), ("oak", 0.6), ("glossy paint", 0.15)])
def test_finish_and_family_set_the_roughness(prompt, roughness):
    assert read_prompt(prompt).roughness == pytest.approx(roughness)


@pytest.mark.parametrize("prompt, family, word", [
    ("red paint with a little dust", "dust", "light"), ("faint dust on blue paint", "dust", "light"),
    ("slightly dusty copper", "dust", "light"), ("paint with moderate dust", "dust", "moderate"),
    ("a thick layer of dust", "dust", "heavy"), ("old paint caked in dust", "dust", "heavy"),
    ("heavily dusty shelf", "dust", "heavy"), ("velvet with dense fuzz", "fuzz", "heavy"),
    ("waxy candle with faint subsurface scattering", "scatter", "light"), ("heavy haze", "haze", "heavy"),
])
def test_strength_words_and_their_synonyms(prompt, family, word):
    assert read_prompt(prompt).strengths == {family: word}


def test_a_strength_word_is_not_taken_from_a_colour_or_another_family():
    assert read_prompt("light blue paint with dust").strengths == {}
    assert read_prompt("light haze and heavy dust").strengths == {"haze": "light", "dust": "heavy"}


def test_captions_strength_words_read_back_to_the_settings_that_word_them():
    pbr = PbrInputs("m", ParamMap.constant(0.5, 0.2, 0.2), ParamMap.constant(0.4), ParamMap.constant(0.0))
    for word in STRENGTHS:
        for synonym in STRENGTH_SYNONYMS[word][:3]:
            reading = read_prompt(f"paint with {synonym} haze and {synonym} dust")
            mat = enhance(pbr, 1, 7, fixed=reading.settings())
            assert f"{word} dust" in enhancement_keywords(mat.settings)
            assert f"{word} haze" in enhancement_keywords(mat.settings)
            lo, hi = FAMILIES["dust"].drawn
            assert _strength(mat.settings["dust_peak"], lo, hi) == word


def test_fixing_a_setting_leaves_every_other_draw_as_it_was():
    pbr = PbrInputs("m", ParamMap.constant(0.5, 0.2, 0.2), ParamMap.constant(0.4), ParamMap.constant(0.0))
    drawn, fixed = enhance(pbr, 3, 5).settings, enhance(pbr, 3, 5, fixed={"dust_peak": 0.85}).settings
    assert fixed["dust_peak"] == 0.85 and drawn["dust_peak"] != 0.85
    assert {k: v for k, v in fixed.items() if k != "dust_peak"} == {k: v for k, v in drawn.items() if k != "dust_peak"}


def test_the_words_base_goes_on_one_colour_materials_and_a_texture_keeps_its_own_unless_asked():
    r = read_prompt("brushed gold metal")
    grey, texture = np.full((1, 1, 3), 0.8), np.random.default_rng(0).uniform(size=(4, 4, 3))
    assert not keeps_base(grey, "auto") and keeps_base(texture, "auto")
    assert keeps_base(grey, "mesh") and not keeps_base(texture, "words")
    with pytest.raises(ValueError, match="auto, mesh or words"):
        keeps_base(grey, "yes")
    base, rough, metal = base_over(r, grey, None, None, keep=False)
    assert base.reshape(3) == pytest.approx(METALS["gold"]) and rough.item() == pytest.approx(0.35)
    assert metal.item() == 1.0
    base, rough, metal = base_over(r, texture, np.full((4, 4, 1), 0.9), np.zeros((4, 4, 1)), keep=True)
    assert base is texture and rough.max() == 0.9 and metal.max() == 0.0  # the file's maps stay
    base, rough, metal = base_over(read_prompt("red"), grey, None, None, keep=False)
    assert rough is None and metal is None  # a colour alone says nothing of roughness and metalness


def test_what_was_read_is_said_in_a_line_per_thing():
    lines = read_prompt("brushed gold metal with a glossy clearcoat").lines()
    assert lines[0] == "Type 2 (Clearcoat)"
    assert lines[1].startswith("colour: gold (#") and lines[2] == "material: brushed gold, metalness 1, roughness 0.35"
    assert read_prompt("red paint with heavy dust").lines()[0] == "Type 1 (Dust): heavy dust"
