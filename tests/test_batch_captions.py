"""Enhancement types per asset (the paper's mix, metals remapped) and captions from what is known."""
from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from batch.assets import collect
from richmat_addon.core.captions import article, caption, colour_name, enhancement_keywords, readable
from richmat_addon.core.colour import gamma_to_linear, linear_to_gamma, srgb_to_linear
from richmat_addon.core.enhancement_types import TYPE_MIX
from torch_models.assets.enhancement_plan import asset_type, material_type


def test_asset_types_follow_the_papers_mix_and_depend_on_the_seed() -> None:
    n = 20000
    counts = Counter(asset_type(f"asset-{i}", 0) for i in range(n))
    for type_, share in enumerate(TYPE_MIX):
        assert abs(counts[type_] / n - share) < 0.015
    assert asset_type("chair-0123456789", 3) == asset_type("chair-0123456789", 3)
    assert any(asset_type(f"a{i}", 0) != asset_type(f"a{i}", 1) for i in range(20))


def test_dielectric_only_types_are_remapped_on_metals() -> None:
    assert material_type(4, metallic=True)[0] == 1 and material_type(5, metallic=True)[0] == 3
    assert material_type(5, metallic=False) == (5, "")
    assert material_type(2, metallic=True) == (2, "")


def test_caption_names_colours_materials_and_enhancement_strength() -> None:
    settings = {"haze_weight": 0.11, "dust_peak": 0.88, "coat_ior": 1.5, "coat_damage": "scratches"}
    assert enhancement_keywords(settings) == ["light haze", "heavy dust", "scratched glossy clearcoat"]
    text = caption("WaterBottle_v2", [
        {"name": "BottleMat", "metallic": False, "mean_base_color": [0.02, 0.1, 0.6], "settings": settings},
        {"name": "Cap.001", "metallic": True, "mean_base_color": [0.6, 0.6, 0.6],
         "settings": {"haze_weight": 0.4, "fuzz_weight": 0.3, "inner_weight": 0.55}}])
    assert text == ("a water bottle v2: blue bottle mat material with light haze, heavy dust, scratched glossy "
                    "clearcoat; light grey cap metal with heavy haze, light fuzz, heavy subsurface scattering")
    assert colour_name([0.0, 0.0, 0.0]) == "black" and colour_name([0.9, 0.02, 0.02]) == "red"
    assert readable("Red") == "red" and "red red" not in caption("Box", [
        {"name": "Red", "metallic": False, "mean_base_color": [0.8, 0.0, 0.0], "settings": {}}])


def test_captions_read_as_english() -> None:
    spoken = {"evo": "an", "bowl": "a", "apple": "an", "umbrella": "an", "unicorn": "a", "european": "a",
              "one": "a", "hour": "an", "house": "a", "8": "an", "80": "an", "11": "an", "7": "a", "110": "a",
              "fbx": "an", "sdf": "an", "mtl": "an", "tv": "a", "usb": "a"}
    assert {word: article(word) for word in spoken} == spoken
    grey = {"metallic": False, "mean_base_color": [0.2, 0.2, 0.2], "settings": {}}
    metal = {**grey, "metallic": True}
    body = caption("EvoBowl", [{**grey, "name": "BodyMaterial"}])
    assert body == "an evo bowl: grey body material with moderate haze"
    assert caption("8_ball", [{**metal, "name": "Steel"}]) == "an 8 ball: grey steel metal with moderate haze"
    assert caption("cone_metal_2", [{**metal, "name": "metal"}]) == "a cone metal 2: grey metal with moderate haze"
    assert caption("UnicornToy", []) == "a unicorn toy: no materials"


def test_an_output_folder_inside_the_input_is_not_collected(tmp_path: Path) -> None:
    (tmp_path / "a.glb").write_bytes(b"x")
    (tmp_path / "out" / "a-1234").mkdir(parents=True)
    (tmp_path / "out" / "a-1234" / "orbit.mp4").write_bytes(b"x")
    (tmp_path / "tex.png").write_bytes(b"x")
    assert [a.key for a in collect(tmp_path, exclude=tmp_path / "out")] == ["a.glb"]


def test_the_corpus_gamma_is_a_stand_in_for_the_srgb_curve() -> None:
    """Captions and the procedural corpus use a 2.2 power; it stays within 0.0085 of the exact curve."""
    x = np.linspace(0.0, 1.0, 4097)
    gap = np.abs(gamma_to_linear(x) - srgb_to_linear(x))
    assert 0.008 < gap.max() < 0.0086
    assert linear_to_gamma(-0.5) == 0.0 and linear_to_gamma(3.0) == 1.0
    assert abs(linear_to_gamma(float(gamma_to_linear(0.46))) - 0.46) < 1e-12
