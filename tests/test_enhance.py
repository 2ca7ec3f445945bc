"""Enhancement rules and procedural masks."""
from __future__ import annotations

import numpy as np
import pytest

from richmat_addon.core import masks
from richmat_addon.core.enhance import enhance, resolve_type
from richmat_addon.core.enhancement_types import TYPE_MIX, TYPES
from richmat_addon.core.maps import ParamMap, PbrInputs
from richmat_addon.core.schema import PARAM_BY_NAME

ALL_MASKS = {**masks.DUST_MASKS, **masks.DAMAGE_MASKS}


@pytest.mark.parametrize("name", sorted(ALL_MASKS))
def test_masks_tile_seamlessly_and_are_seeded(name):
    fn = ALL_MASKS[name]
    m = fn(128, np.random.default_rng(3))
    assert m.shape == (128, 128) and m.min() >= 0 and m.max() <= 1 and m.max() > 0
    assert np.array_equal(m, fn(128, np.random.default_rng(3)))
    assert not np.array_equal(m, fn(128, np.random.default_rng(4)))
    # The jump across the wrap-around seam is no larger than jumps inside the tile.
    inner = np.abs(np.diff(m, axis=1)).mean()
    seam = np.abs(m[:, 0] - m[:, -1]).mean()
    assert seam <= 3 * inner + 1e-6, (seam, inner)
    if name in masks.DAMAGE_MASKS:
        assert set(np.unique(m)) <= {0.0, 1.0}


def test_triplanar_weights_pick_the_aligned_projection():
    mask = np.zeros((8, 8), np.float32)
    mask[:, :4] = 1.0
    pos = np.array([[0.1, 0.9, 0.1]])
    up = masks.triplanar(mask, pos, np.array([[0.0, 0.0, 1.0]]))  # uses (x, y)
    side = masks.triplanar(mask, pos, np.array([[1.0, 0.0, 0.0]]))  # uses (y, z)
    assert up[0] == mask[0, 7] and side[0] == mask[7, 0]


def pbr(base=(0.5, 0.4, 0.3), rough=0.5, metal=0.0, size=None, name="m"):
    def m(v, c):
        v = np.broadcast_to(np.asarray(v, np.float32), (c,))
        return ParamMap(np.broadcast_to(v, (size[0], size[1], c)).copy() if size else v.copy())
    return PbrInputs(name, m(base, 3), m(rough, 1), m(metal, 1))


@pytest.mark.parametrize("type_", [t.index for t in TYPES])
def test_constants_stay_constant_and_in_range(type_):
    mat = enhance(pbr(), type_, seed=1)
    for name, m in mat.params.items():
        assert m.is_constant, name
        p = PARAM_BY_NAME[name]
        assert (m.value >= p.lo).all() and (m.value <= p.hi).all(), name
    assert mat.settings["p"] > 2 and mat.settings["q"] < 2 and mat.settings["s"] > 1
    assert enhance(pbr(), type_, seed=1).settings == mat.settings


@pytest.mark.parametrize("r", [0.0, 0.05, 0.5, 0.95, 1.0])
def test_core_is_sharper_than_haze(r):
    mat = enhance(pbr(rough=r), 0, seed=2)
    core, haze = mat.params["alpha_core"].value[0], mat.params["alpha_haze"].value[0]
    assert core <= max(r * r, PARAM_BY_NAME["alpha_core"].lo) + 1e-7 and core <= haze


def test_textures_keep_their_resolution_and_only_varying_maps_are_textures():
    p = pbr(size=(24, 40))
    p.roughness = ParamMap(np.linspace(0, 1, 24 * 40, dtype=np.float32).reshape(24, 40, 1))
    mat = enhance(p, 2, seed=5)
    assert mat.params["alpha_core"].shape == (24, 40)
    assert mat.params["diel_ior"].is_constant and mat.params["dust_weight"].is_constant


@pytest.mark.parametrize("type_", [1, 2, 3])
def test_masks_take_a_non_square_texture_s_shape(type_):
    """UV-space dust and clearcoat damage on a 24 x 40 texture are 24 x 40 maps (they were 40 x 40)."""
    masked = set()
    for seed in range(8):
        mat = enhance(pbr(size=(24, 40)), type_, seed=seed)
        for name in ("dust_weight", "coat_weight"):
            if not mat.params[name].is_constant:
                assert mat.params[name].shape == (24, 40), (seed, name)
                masked.add(name)
    assert masked  # some seed drew a mask


def test_dust_prefers_upward_faces():
    n = np.zeros((16, 16, 3), np.float32)
    n[:8, :, 2], n[8:, :, 2] = 1.0, -1.0
    pos = np.random.default_rng(0).random((16, 16, 3)).astype(np.float32)
    mat = enhance(pbr(), 1, seed=3, world_normals=ParamMap(n), world_positions=ParamMap(pos))
    dust = mat.params["dust_weight"].value[..., 0]
    assert dust[:8].min() > 0 and dust[8:].max() == 0


def test_scattering_types_on_metal_are_refused_or_remapped():
    metal = pbr(metal=1.0, name="steel")
    with pytest.raises(ValueError, match="steel.*0-3"):
        enhance(metal, 5)
    assert resolve_type(metal, 4, 0)[0] == 1 and "metallic" in resolve_type(metal, 4, 0)[1]


def test_auto_follows_the_paper_mix_and_never_scatters_metal():
    counts = np.bincount([resolve_type(pbr(name=f"m{i}"), "auto", 0)[0] for i in range(3000)],
                         minlength=6) / 3000
    assert np.allclose(counts, TYPE_MIX, atol=0.03), counts
    metal = {resolve_type(pbr(metal=1.0, name=f"m{i}"), "auto", 0)[0] for i in range(300)}
    assert metal <= {0, 1, 2, 3}


def test_nan_and_out_of_range_texels_are_clamped_with_a_warning():
    p = pbr(size=(4, 4))
    p.roughness.value[0, 0, 0] = np.nan
    p.base_color.value[1, 1] = 2.0
    with pytest.warns(UserWarning) as caught:
        mat = enhance(p, 0, seed=0)
    messages = [str(w.message) for w in caught]
    assert any("roughness: 1 non-finite" in m for m in messages)
    assert any("base colour: 0 non-finite and 3 out-of-range" in m for m in messages)
    assert all(np.isfinite(m.value).all() for m in mat.params.values())


@pytest.mark.parametrize("base", [(0, 0, 0), (1, 1, 1)])
def test_black_and_white_base_colours(base):
    mat = enhance(pbr(base=base, metal=1.0), 3, seed=0)
    assert all(np.isfinite(m.value).all() for m in mat.params.values())
