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


def _plane_view(depths: torch.Tensor) -> tuple[views.IntrinsicViews, views.Cameras]:
    """One camera at z = 5 looking down -Z at surfaces facing it, ``depths`` (H, W) below the camera
    per pixel (inf: background), every pixel's UV at the centre of texel (0, 0) of a 1 x 1 texture."""
    h, w = depths.shape
    cams = views.Cameras(w, float(w), torch.tensor([[[1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 5], [0, 0, 0, 1]]],
                                                  dtype=torch.float64))
    covered = depths.isfinite()
    d = torch.where(covered, depths, 0.0)
    ys, xs = torch.meshgrid(torch.arange(h) + 0.5 - h / 2, torch.arange(w) + 0.5 - w / 2, indexing="ij")
    positions = torch.stack([xs * d / w, -ys * d / w, 5 - d], -1)[None]
    normals = torch.tensor([0.0, 0.0, 1.0]).expand(1, h, w, 3)
    return views.IntrinsicViews(normals, positions, torch.zeros(1, h, w, 3), covered.float()[None],
                                torch.full((1, h, w, 2), 0.5), None), cams


def test_rim_trust_marks_silhouettes_and_occlusion_boundaries():
    depths = torch.full((8, 12), 5.0)
    depths[:, 6:] = 3.0  # a nearer surface on the right: an occlusion boundary between columns 5 and 6
    depths[:, 11] = float("inf")  # background in the last column: a silhouette
    view, cams = _plane_view(depths)
    trust = projection.rim_trust(view, cams, width=1)[0]
    near = torch.zeros(12, dtype=torch.bool)
    near[[4, 5, 6, 7, 10, 11]] = True
    assert bool((trust[:, near] == projection.RIM_TRUST).all()) and bool((trust[:, ~near] == 1).all())


def test_a_texel_seen_only_near_a_rim_is_seen_and_prefers_a_clean_view():
    view, cams = _plane_view(torch.full((1, 2), 5.0))
    values = torch.tensor([[[[1.0], [3.0]]]])  # two pixels on the one texel
    charts = torch.ones(1, 1, dtype=torch.bool)
    both_rim = projection.project(values, view, cams, charts, torch.zeros(1), trust=torch.full((1, 1, 2), 0.01))
    assert bool(both_rim.seen.all()) and float(both_rim.texture[0, 0, 0]) == pytest.approx(2.0)
    one_clean = projection.project(values, view, cams, charts, torch.zeros(1), trust=torch.tensor([[[0.01, 1.0]]]))
    assert bool(one_clean.seen.all()) and float(one_clean.texture[0, 0, 0]) == pytest.approx(3.0, abs=0.03)
