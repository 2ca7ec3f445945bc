"""The torch preview renderer against Cycles and against exact values."""
from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest
import torch

from richmat_addon.core.folder_io import read_exr
from richmat_addon.core.schema import default_vector
from torch_models.brdf.model import LayeredBsdf, params_from_vectors
from torch_models.render.ball import render_ball, shade_gbuffer
from torch_models.render.camera import filter_offsets, primary_rays
from torch_models.render.envmap import EnvMap, read_probe
from torch_models.render.flip import mean_flip
from torch_models.render.preview_scene import PreviewScene
from torch_models.render.tonemap import agx

REPO = Path(__file__).resolve().parents[1]
PROBE = REPO / "torch_models" / "data" / "studio_small_03_512.hdr"


@pytest.fixture(scope="module")
def env() -> EnvMap:
    return EnvMap.load(PROBE)


def _plain_bsdf(base=(0.5, 0.2, 0.1), **overrides: float) -> LayeredBsdf:
    params = params_from_vectors(torch.tensor(default_vector(), dtype=torch.float32)[None])
    for k, v in overrides.items():
        params[k] = torch.tensor([[v]])
    return LayeredBsdf(params, torch.tensor([base]))


def test_env_sampling_pdf_is_normalised_and_consistent(env: EnvMap) -> None:
    gen = torch.Generator().manual_seed(3)
    d, pdf = env.sample(torch.rand(100_000, 4, generator=gen))
    assert torch.allclose(d.norm(dim=-1), torch.ones(len(d)), atol=1e-5)
    rel = (pdf - env.pdf(d)).abs() / pdf
    assert (rel > 1e-3).float().mean() < 1e-3  # only texel-boundary rounding may differ
    # Integral of the pdf over the sphere, exactly by pixel centres.
    h, w = env.height, env.width
    rows, cols = torch.meshgrid(torch.arange(h), torch.arange(w), indexing="ij")
    from torch_models.render.envmap import uv_to_direction
    centres = uv_to_direction(torch.stack([(cols + 0.5) / w, 1 - (rows + 0.5) / h], -1).reshape(-1, 2))
    total = (env.pdf(centres).reshape(h, w) * env.pixel_solid_angle[:, None]).sum()
    assert total.item() == pytest.approx(1.0, abs=1e-4)
    # The importance-sampled estimate of the probe's irradiance integral matches quadrature.
    quad = (env.rgb * env.pixel_solid_angle[:, None, None]).sum((0, 1))
    estimate = (env.radiance(d) / pdf[:, None]).mean(0)
    assert torch.allclose(estimate, quad, rtol=0.03)


def test_pixel_filter_offsets_follow_blackman_harris() -> None:
    x = filter_offsets(torch.rand(200_000, generator=torch.Generator().manual_seed(0)))
    assert x.abs().max() <= 1.5
    # Variance of the Blackman-Harris window over [-1.5, 1.5] by quadrature.
    grid = torch.linspace(-1.5, 1.5, 20001, dtype=torch.float64)
    from torch_models.render.camera import blackman_harris
    wgt = blackman_harris(grid)
    var = float((wgt * grid ** 2).sum() / wgt.sum())
    assert float(x.double().var()) == pytest.approx(var, rel=0.02)


def test_white_furnace_ball_is_white() -> None:
    """White probe, white Lambertian (IOR 1: the dielectric reflects nothing): every ball pixel is 1."""
    white = EnvMap(np.ones((32, 64, 3), np.float32))
    bsdf = _plain_bsdf((1.0, 1.0, 1.0), diel_ior=1.0)
    res = render_ball(lambda n: bsdf, white, PreviewScene(resolution=24), spp=64, seed=0)
    inside = res.alpha == 1.0
    assert inside.sum() > 200
    assert res.rgb[inside].mean() == pytest.approx(1.0, abs=0.01)
    assert np.abs(res.rgb[inside] - 1.0).max() < 0.12
    assert (res.rgb[res.alpha == 0] == 0).all()


def test_render_is_deterministic_per_seed(env: EnvMap) -> None:
    bsdf = _plain_bsdf()
    a, b, c = (render_ball(lambda n: bsdf, env, PreviewScene(resolution=24), 4, s) for s in (5, 5, 6))
    assert np.array_equal(a.rgb, b.rgb)
    assert not np.array_equal(a.rgb, c.rgb)


def test_flip_convention() -> None:
    rng = np.random.default_rng(0)
    img = rng.uniform(0.2, 0.8, (32, 32, 3)).astype(np.float32)
    assert mean_flip(img, img) == 0.0
    assert 0.02 < mean_flip(img, np.clip(img + 0.1, 0, 1)) < 0.5
    with pytest.raises(ValueError):
        mean_flip(img, img[..., :1])


def test_probe_errors_name_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "probe.hdr"
    bad.write_bytes(b"not an image")
    with pytest.raises(ValueError, match="probe.hdr"):
        read_probe(bad)


def test_camera_and_probe_conventions_match_cycles(blender_run, tmp_path: Path, env: EnvMap) -> None:
    """Cycles' view of the bare probe through the preview camera equals our env lookup."""
    blender_run(f"""
        import bpy
        from pathlib import Path
        from torch_models.render.preview_scene import PreviewScene
        from support import blender_preview_scene
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        blender_preview_scene.setup(scene, PreviewScene(resolution=48, probe_rotation_deg=30.0), Path({str(PROBE)!r}),
                                    None, samples=32, with_ball=False)
        blender_preview_scene.render_exr(scene, Path({str(tmp_path / 'bg.exr')!r}))
    """)
    cycles = read_exr(tmp_path / "bg.exr")[..., :3]
    rotated = EnvMap(env.rgb.numpy(), rotation_deg=30.0)
    scene = PreviewScene(resolution=48)
    gen = torch.Generator().manual_seed(0)
    ours = sum(rotated.radiance(primary_rays(scene, torch.rand(48 * 48, 2, generator=gen))[1])
               for _ in range(64)) / 64
    ours = ours.reshape(48, 48, 3).numpy()
    assert np.abs(cycles - ours).mean() / ours.mean() < 0.01
    # Not a coincidence of a uniform probe: the unrotated view differs clearly.
    plain = sum(env.radiance(primary_rays(scene, torch.rand(48 * 48, 2, generator=gen))[1])
                for _ in range(8)) / 8
    assert np.abs(cycles - plain.reshape(48, 48, 3).numpy()).mean() / ours.mean() > 0.05


def test_mesh_ball_renders_like_the_point_ball(blender_run, tmp_path: Path) -> None:
    """The UV-sphere ball that EEVEE draws renders in Cycles like the exact point ball, so EEVEE's renders
    compare fairly with Cycles' references; and the switch really swaps the geometry."""
    vertices = blender_run(f"""
        import bpy
        from pathlib import Path
        from torch_models.render.preview_scene import PreviewScene
        from support import blender_preview_scene
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        material = bpy.data.materials.new("plain")
        blender_preview_scene.setup(scene, PreviewScene(resolution=48), Path({str(PROBE)!r}), material, samples=32)
        ball = bpy.data.objects[blender_preview_scene.BALL]
        vertices = []
        for on in (False, True):
            blender_preview_scene.use_mesh_ball(on)
            vertices.append(len(ball.evaluated_get(bpy.context.evaluated_depsgraph_get()).data.vertices))
            blender_preview_scene.render_exr(scene, Path({str(tmp_path)!r}) / f"ball_{{on}}.exr")
        print("RESULT", vertices)
    """)
    assert vertices[0] == 0 and vertices[1] > 10_000  # a point, then the fine UV sphere
    point, mesh = (read_exr(tmp_path / f"ball_{on}.exr") for on in (False, True))
    assert np.abs(point[..., 3] - mesh[..., 3]).mean() < 0.005  # the same silhouette
    assert np.abs(point[..., :3] - mesh[..., :3]).mean() / point[..., :3].mean() < 0.03


def test_agx_matches_blender(blender_run, tmp_path: Path) -> None:
    """Blender saving a float image with the AgX view gives the same 8-bit values as ours."""
    ramp = np.linspace(0.0, 3.0, 16 * 16 * 3, dtype=np.float32).reshape(16, 16, 3)
    ramp[..., 1] *= 0.3  # saturated colours too, not just greys
    np.save(tmp_path / "ramp.npy", ramp)
    blender_run(f"""
        import bpy, numpy as np
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        scene.view_settings.view_transform = "AgX"
        scene.view_settings.look = "None"
        scene.render.image_settings.file_format = "PNG"
        scene.render.image_settings.color_depth = "8"
        ramp = np.load({str(tmp_path / 'ramp.npy')!r})
        img = bpy.data.images.new("ramp", 16, 16, float_buffer=True)
        rgba = np.concatenate([ramp[::-1], np.ones((16, 16, 1), np.float32)], -1)
        img.pixels.foreach_set(rgba.ravel())
        img.save_render({str(tmp_path / 'agx.png')!r}, scene=scene)
    """)
    from PIL import Image

    blender = np.asarray(Image.open(tmp_path / "agx.png").convert("RGB"), np.float32) / 255.0
    ours = agx(ramp)
    assert np.abs(blender - ours).max() <= 2.5 / 255.0
    assert np.abs(blender - np.clip(ramp, 0, 1) ** (1 / 2.2)).max() > 0.05  # AgX is not a plain gamma


def test_ball_agrees_with_cycles(blender_run, tmp_path: Path, env: EnvMap) -> None:
    """A small, low-sample version of bench/material/agreement.py: one coated material."""
    from support.agreement_cases import cases

    case = next(c for c in cases(7, 1, 0) if c.name.startswith("type3"))
    blender_run(f"""
        import bpy, json
        from pathlib import Path
        from support.agreement_cases import Case
        from torch_models.render.preview_scene import PreviewScene
        from richmat_addon.blender import cycles_builder
        from support import blender_preview_scene
        case = Case(**json.loads({json.dumps(asdict(case))!r}))
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        cycles_builder.enable_osl(scene)
        mat = cycles_builder.build_material(case.material(), {{}}, case.name, node=case.graph_node())
        blender_preview_scene.setup(scene, PreviewScene(resolution=48), Path({str(PROBE)!r}), mat, 128)
        blender_preview_scene.render_exr(scene, Path({str(tmp_path / 'ball.exr')!r}))
    """)
    params = {k: torch.tensor([v]) for k, v in case.params.items()}
    bsdf = LayeredBsdf(params, torch.tensor([case.base_color]))
    ours = render_ball(lambda n: bsdf, env, PreviewScene(resolution=48), 128, 0)
    cycles = read_exr(tmp_path / "ball.exr")[..., :3]
    assert math.isclose(float(cycles.mean()), float(ours.rgb.mean()), rel_tol=0.03)
    assert mean_flip(agx(cycles), agx(ours.rgb)) < 0.06


def test_gbuffer_shading_matches_the_ball(env: EnvMap) -> None:
    """The ball's own G-buffer (pixel-centre normals and view directions) shades like the ball."""
    scene = PreviewScene(resolution=32)
    origin, d = primary_rays(scene, torch.full((32 * 32, 2), 0.5))  # offset 0: pixel centres
    from torch_models.render.camera import hit_sphere
    hit, p = hit_sphere(origin, d, 1.0)
    normals = (p / p.norm(dim=-1, keepdim=True)).reshape(32, 32, 3).numpy()
    views = (-d).reshape(32, 32, 3).numpy()
    bsdf = _plain_bsdf()
    shaded = shade_gbuffer(lambda n: bsdf, env, normals, views, hit.reshape(32, 32).numpy(), 256, 0)
    ball = render_ball(lambda n: bsdf, env, scene, 256, 0)
    inner = ball.alpha == 1.0
    assert (shaded[~hit.reshape(32, 32).numpy()] == 0).all()
    assert np.isclose(shaded[inner].mean(), ball.rgb[inner].mean(), rtol=0.03)
