"""The enhancement's amount and Auto's lighter touch on dark materials, on the milk truck's tyres."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from richmat_addon.core.enhance import auto_touch, baseline, enhance, resolve_type
from richmat_addon.core.enhancement_types import TYPES
from richmat_addon.core.maps import ParamMap, PbrInputs
from richmat_addon.core.uv_raster import rasterize
from torch_models.assets.gltf_container import load_gltf
from torch_models.assets.gltf_materials import read_materials
from torch_models.assets.gltf_mesh import read_geometry
from torch_models.cli_enhance import pil_decode
from torch_models.material_albedo import luminance, mean_albedo, texel_uvs

STRIDE = 8  # the truck's 2048 px atlas read at 256 px: the tyre keeps about 10 000 texels
AUTO_TOLERANCE = 0.15  # Auto's uplift of the tyres may lift their mean albedo by this share at most


@pytest.fixture
def tyres(shared_assets: Path):
    """The truck's "wheels" material (the tyre region of its atlas), its world maps and covered texels."""
    doc = load_gltf(shared_assets / "models" / "CesiumMilkTruck.glb")
    materials = read_materials(doc, pil_decode)
    index = [m.pbr.name for m in materials].index("wheels")
    pbr = materials[index].pbr
    pbr = PbrInputs(pbr.name, *(m if m.is_constant else ParamMap(m.value[::STRIDE, ::STRIDE])
                                for m in (pbr.base_color, pbr.roughness, pbr.metalness)))
    g = read_geometry(doc)[index]
    raster, why = rasterize(g.positions, g.normals, g.uvs, g.indices, pbr.base_color.shape)
    assert raster is not None, why
    return pbr, ParamMap(raster.normals), ParamMap(raster.positions), texel_uvs(raster.coverage)


def test_auto_keeps_the_tyres_dark_and_amount_zero_gives_back_the_pbr_material(tyres):
    pbr, normals, positions, uv = tyres
    before = luminance(mean_albedo(baseline(pbr), uv))
    assert before < 0.06  # black rubber
    auto, _ = resolve_type(pbr, "auto", 0)
    lifts = {}
    for type_ in range(len(TYPES)):
        full = luminance(mean_albedo(enhance(pbr, type_, 0, normals, positions), uv))
        touched = luminance(mean_albedo(enhance(pbr, type_, 0, normals, positions, touch=True), uv))
        lifts[type_] = (full / before, touched / before)
    # The rules as drawn grey the tyres (every type but haze alone lifts them by a fifth or more; the
    # coat's Fresnel more than doubles them); Auto's touch keeps the type it draws within the tolerance.
    assert all(full > 1.2 for t, (full, _) in lifts.items() if t > 0), lifts
    assert lifts[auto][1] < 1 + AUTO_TOLERANCE, lifts
    assert all(touched < full for full, touched in lifts.values())
    # Amount 0 is the PBR material: every parameter equal to the baseline's, so the same albedo.
    zero, plain = enhance(pbr, auto, 0, normals, positions, amount=0.0), baseline(pbr)
    for name, m in zero.params.items():
        np.testing.assert_allclose(m.value, plain.params[name].value, atol=1e-6, err_msg=name)
    assert luminance(mean_albedo(zero, uv)) == pytest.approx(before, rel=1e-5)


def test_amount_scales_every_weight_and_one_is_the_rules_as_drawn():
    pbr = PbrInputs("paint", ParamMap.constant(0.5, 0.1, 0.1), ParamMap.constant(0.6), ParamMap.constant(0.0))
    full, half = enhance(pbr, 5, 3), enhance(pbr, 5, 3, amount=0.5)
    assert enhance(pbr, 5, 3, amount=1.0).params.keys() == full.params.keys()
    for name in ("haze_weight", "dust_weight", "coat_weight", "inner_weight", "subsurf_weight"):
        assert half.params[name].value[0] == pytest.approx(0.5 * full.params[name].value[0], rel=1e-5), name
    assert half.settings["amount"] == 0.5 and "amount" not in full.settings  # 1 keeps today's record
    touch = auto_touch(PbrInputs("grey", ParamMap(np.array([[[0.02] * 3, [0.18] * 3, [0.9] * 3]], np.float32)),
                                 ParamMap.constant(0.5), ParamMap.constant(0.0))).value[0, :, 0]
    np.testing.assert_allclose(touch, [(0.02 / 0.18) ** 1.5, 1.0, 1.0], rtol=1e-5)
