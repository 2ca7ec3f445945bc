"""Views back into texture space: a known texture survives render + projection; holes get filled."""
import numpy as np
import pytest
import torch

from richmat_addon.core.uv_raster import rasterize as uv_rasterize
from torch_models.generator import projection, views
from torch_models.generator.procedural import make_mesh

torch.set_num_threads(1)
SIZE = 64


@pytest.fixture(scope="module")
def scene():
    mesh = make_mesh("sphere", np.random.default_rng(3))
    raster, _ = uv_rasterize(mesh.positions, mesh.normals, mesh.uvs, mesh.faces, (SIZE, SIZE), padding=4)
    # a smooth known texture: a function of the world position of each texel (seamless across charts,
    # padded around them as real textures are, so bilinear lookups at chart borders stay right)
    p = raster.positions
    texture = np.stack([np.sin(3 * p[..., 0]), np.cos(2 * p[..., 1]), p[..., 2]], -1).astype(np.float32)
    return mesh, torch.from_numpy(raster.coverage), texture


def test_splat_puts_a_texel_centre_sample_into_that_texel():
    uv = torch.tensor([[[[(5 + 0.5) / 8, (2 + 0.5) / 8]]]])
    acc, wsum = projection.splat(torch.ones(1, 1, 1, 2), uv, torch.ones(1, 1, 1), (8, 8))
    assert float(wsum[2, 5]) == pytest.approx(1.0) and float(wsum.sum()) == pytest.approx(1.0)
    assert torch.equal(acc[2, 5], torch.ones(2))


def test_known_texture_is_reproduced_on_seen_texels(scene):
    mesh, charts, texture = scene
    cams = views.orbit_cameras(16, 128)
    iv = views.render_intrinsics(mesh, cams, np.zeros((1, 1, 3), np.float32), texture)
    out = projection.project(iv.latents, iv, cams, charts, torch.zeros(3))
    seen = out.seen
    assert float(seen.sum()) > 0.6 * float(charts.sum())  # 16 views of a sphere see most of it
    err = (out.texture - torch.from_numpy(texture)).abs().amax(-1)[seen]
    assert float(err.median()) < 0.005 and float(err.quantile(0.95)) < 0.03
    assert bool((out.seen | out.inpainted | out.fallback)[charts].all())
    assert bool(out.texture.isfinite().all())


def test_unseen_texels_are_inpainted_or_get_the_fallback(scene):
    mesh, charts, texture = scene
    cams = views.orbit_cameras(1, 64)  # one view: most of the sphere is never seen
    iv = views.render_intrinsics(mesh, cams, np.zeros((1, 1, 3), np.float32), texture)
    fallback = torch.tensor([7.0, 7.0, 7.0])
    out = projection.project(iv.latents, iv, cams, charts, fallback)
    stats = out.stats(charts)
    assert stats["seen"] < 0.5 and stats["seen"] + stats["inpainted"] + stats["fallback"] == pytest.approx(1.0)
    assert stats["fallback"] > 0  # some UV islands lie wholly on the far side
    assert torch.equal(out.texture[out.fallback], fallback.expand(int(out.fallback.sum()), 3))
    lo, hi = out.texture[out.seen].min(0).values, out.texture[out.seen].max(0).values
    filled = out.texture[out.inpainted]
    assert bool(((filled >= lo - 1e-5) & (filled <= hi + 1e-5)).all())  # means of known values only


def test_erosion_drops_seen_texels_next_to_holes():
    charts = torch.ones(12, 12, dtype=torch.bool)
    known = torch.zeros(12, 12, dtype=torch.bool)
    known[:, :8] = True
    eroded = known & ~projection._grow(charts & ~known, 4)
    assert bool(eroded[:, :4].all()) and not bool(eroded[:, 4:].any())
