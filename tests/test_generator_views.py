"""The torch intrinsic-view rasteriser against batch's Cycles passes of the same asset."""
import json
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
from scipy.ndimage import binary_erosion

from torch_models.generator import corpus, views
from tests.test_generator_text import text_encoder
from richmat_addon.core.folder_io import read_exr

torch.set_num_threads(1)
DATA = Path(__file__).parent / "data" / "generator_batch"
ASSET = DATA / "cone_metal_2"


def _glb_mesh() -> views.Mesh:
    """The GLB as Blender imports it: glTF Y up -> Blender Z up, (x, y, z) -> (x, -z, y)."""
    geom = list(trimesh.load(DATA / "cone_metal_2.glb").geometry.values())[0]

    def z_up(a):
        a = np.asarray(a, np.float32)
        return np.stack([a[:, 0], -a[:, 2], a[:, 1]], 1)

    uv = np.asarray(geom.visual.uv, np.float32).copy()
    uv[:, 1] = 1 - uv[:, 1]  # trimesh keeps v up; glTF (and views.py) count v down
    return views.Mesh(z_up(geom.vertices), z_up(geom.vertex_normals), uv, np.asarray(geom.faces, np.int64))


@pytest.fixture(scope="module")
def both():
    with text_encoder():
        batch = corpus.batch_samples(DATA)[0]
    cams = views.Cameras.from_record(json.loads((ASSET / "cameras.json").read_text()))
    m = ASSET / "materials" / "metal"
    latents = np.concatenate([read_exr(m / "neural" / "latent_0.exr"), read_exr(m / "neural" / "latent_1.exr")], -1)
    no_prior = np.zeros_like(latents)  # sample_from_views wants the two priors too; not compared here
    ours = views.render_intrinsics(_glb_mesh(), cams, read_exr(m / "base_color.exr"),
                                   np.concatenate([latents, no_prior, no_prior], -1), supersample=4)
    return batch, corpus.sample_from_views(batch.asset_id, batch.caption, batch.type, ours)


def test_orbit_cameras_repeat_batch_orbit():
    record = json.loads((ASSET / "cameras.json").read_text())
    theirs = views.Cameras.from_record(record)
    first = theirs.camera_to_world[0, :3, 3]
    azimuth0 = float(torch.atan2(first[1], first[0]))
    ours = views.orbit_cameras(len(record["frames"]), theirs.resolution, azimuth0)
    assert ours.focal_px == pytest.approx(theirs.focal_px)
    assert torch.allclose(ours.camera_to_world, theirs.camera_to_world, atol=1e-5)


def test_rasterised_maps_match_cycles_passes(both):
    batch, ours = both
    assert batch.target.shape == ours.target.shape == (4, 6, 32, 32)
    cb, co = batch.conditions[:, -1] > 0, ours.conditions[:, -1] > 0
    iou = float((cb & co).sum() / (cb | co).sum())
    assert iou > 0.95
    inner = torch.from_numpy(np.stack([binary_erosion(m) for m in (cb & co).numpy()]))
    assert int(inner.sum()) > 150

    def err(a, b):
        return (a - b).abs().amax(1)[inner]

    positions = err(batch.conditions[:, 3:6], ours.conditions[:, 3:6])
    # same cameras, same geometry; pixel footprints straddling an edge average differently
    assert float(positions.median()) < 1e-3 and float(positions.quantile(0.9)) < 5e-3
    base = err(batch.conditions[:, 6:9], ours.conditions[:, 6:9])
    assert float(base.median()) < 0.005 and float(base.quantile(0.9)) < 0.01
    normals = err(batch.conditions[:, 0:3], ours.conditions[:, 0:3])
    assert float(normals.median()) < 0.03  # creases and AA filter shape differ a little
    assert float(batch.conditions[:, views.PBR_CHANNELS].abs().max()) == 0.0  # batch renders no PBR passes
    latents = err(batch.target, ours.target)
    assert float(latents.median()) < 0.03 and float(latents.quantile(0.9)) < 0.06


def test_batch_sample_carries_caption_type_and_text():
    s = corpus.batch_samples(DATA)[0]
    assert s.caption == (ASSET / "caption.txt").read_text().strip()
    assert "dust" in s.caption and s.type == json.loads((ASSET / "manifest.json").read_text())["enhancement_type"]
    assert s.text.shape == (384,) and abs(float(s.text.norm()) - 1) < 1e-5
    # batch knows no roughness or metalness: its prior is the unknown-PBR uplift, made per pixel
    cover = s.conditions[:, -1] > 0
    assert torch.equal(s.conditions[:, views.PRIOR_CHANNELS], s.unknown_prior)
    assert float(s.unknown_prior.abs().amax(1)[cover].min()) > 0 and float(s.unknown_prior.abs().amax(1)[~cover].max()) == 0
