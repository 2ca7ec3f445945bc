"""`generate`: prompt keywords, mesh input, and the whole command on a tiny checkpoint."""
import json
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
from PIL import Image

from richmat_addon.core import material_folder, named_colours, neural_folder
from richmat_addon.core.enhance import enhance
from richmat_addon.core.folder_io import read_exr
from richmat_addon.core.maps import ParamMap, PbrInputs
from richmat_addon.core.prompt import prompt_type
from torch_models.cli import main
from torch_models.cli_generate import PREVIEW_FRAMES, PREVIEW_SIZE
from torch_models.generator import guidance_for
from tests.test_generator_text import text_encoder
from tests.test_generator_train import TINY

torch.set_num_threads(1)
GLB = Path(__file__).parent / "data" / "generator_batch" / "cone_metal_2.glb"


def test_prompt_keywords_name_the_enhancement_type():
    assert prompt_type("a dusty copper kettle")[0] == 1
    assert prompt_type("red car paint with a thick glossy clear coat")[0] == 2
    assert prompt_type("old lacquered box covered in dust")[0] == 3
    assert prompt_type("soft velvet cushion")[0] == 4
    assert prompt_type("waxy candle with a glaze")[0] == 5
    assert prompt_type("velvet", metallic=True)[0] == 1  # no fuzz on metals, as the enhancer
    type_, warnings = prompt_type("something shiny")
    assert type_ == 0 and "no enhancement keyword" in warnings[0]
    assert prompt_type("white silver metal with moderate haze") == (0, [])  # haze is every type's: understood


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    root = tmp_path_factory.mktemp("gen_ckpt")
    cfg = dict(TINY, corpus=dict(TINY["corpus"], procedural=2), steps=3, warmup=1, checkpoint_every=3)
    (root / "tiny.json").write_text(json.dumps(cfg))
    with text_encoder():
        assert main(["train-generator", "--config", str(root / "tiny.json"), "--out", str(root / "run")]) == 0
    return root / "run"


def test_generate_writes_latent_textures_and_a_preview(checkpoint, tmp_path):
    out = tmp_path / "out"
    args = [str(GLB), "--prompt", "white silver metal with light dust", "--out", str(out), "--views", "3",
            "--steps", "2", "--texture-size", "32", "--checkpoint", str(checkpoint)]
    assert main(["generate", *args]) == 0
    a, b = read_exr(out / "latent_0.exr"), read_exr(out / "latent_1.exr")
    assert a.shape == b.shape == (32, 32, 3)
    assert np.isfinite(a).all() and np.abs(np.concatenate([a, b], -1)).max() <= 1.0 + 1e-3
    record = neural_folder.read(out).record
    assert record["type"] == 1 and record["views"] == 3 and len(record["cameras"]) == 3
    assert record["guidance"] == guidance_for(1)  # the one it sampled with, not None
    assert record["coverage"] == record["projection"]  # one material: the mesh's share is its own
    guarded = record["energy_scale"] == "energy_scale.exr"  # the guard ran; its map is written when it darkened
    assert guarded == (record["texels_darkened_by_guard"] > 0) == (out / "energy_scale.exr").exists()
    share = record["projection"]
    assert share["seen"] > 0 and share["seen"] + share["inpainted"] + share["fallback"] == pytest.approx(1.0)
    with Image.open(out / "preview.png") as im:
        assert im.size == (PREVIEW_FRAMES * PREVIEW_SIZE, PREVIEW_SIZE) and im.size[0] >= 512
        lit = np.asarray(im)[..., :3]
        assert lit.max() > 0 and (lit.max(-1) > 0).mean() > 0.1  # the object is lit and fills the frame
    again = tmp_path / "again"
    assert main(["generate", *args[:4], str(again), *args[5:], "--no-preview", "--no-energy-guard"]) == 0
    assert np.array_equal(read_exr(again / "latent_0.exr"), a)  # deterministic per seed


def test_mesh_without_uvs_is_unwrapped(checkpoint, tmp_path):
    obj = tmp_path / "ball.obj"
    trimesh.creation.icosphere(subdivisions=2).export(str(obj))
    out = tmp_path / "out"
    assert main(["generate", str(obj), "--prompt", "plastic ball", "--out", str(out), "--views", "2", "--steps", "1",
                 "--texture-size", "16", "--checkpoint", str(checkpoint), "--no-preview", "--no-energy-guard"]) == 0
    record = neural_folder.read(out).record
    assert any("xatlas" in n for n in record["notes"]) and record["type"] == 0 and record["warnings"]
    mesh = trimesh.load(out / "mesh.glb", force="mesh")
    assert mesh.visual.uv is not None and len(mesh.visual.uv) == len(mesh.vertices)


def test_missing_checkpoint_is_bad_input(tmp_path):
    assert main(["generate", str(GLB), "--prompt", "x", "--out", str(tmp_path / "o"),
                 "--checkpoint", str(tmp_path / "none")]) == 2


@pytest.mark.parametrize("flag", ["--steps", "--views", "--samples"])
def test_zero_steps_views_or_samples_is_bad_input_and_writes_nothing(flag, tmp_path):
    out = tmp_path / "o"
    assert main(["generate", str(GLB), "--prompt", "x", "--out", str(out), flag, "0"]) == 2
    assert not out.exists()


def test_a_mostly_inpainted_texture_is_warned_about(checkpoint):
    from torch_models.generator import generate as gen
    from torch_models.generator.mesh_input import load_mesh
    from torch_models.generator.views import orbit_cameras

    model, cfg = gen.load_generator(checkpoint)
    inp = load_mesh(GLB)
    one = gen.generate(inp, "silver metal with light dust", model, cfg, steps=1, texture_size=32, guard_energy=False,
                       cameras=orbit_cameras(1, cfg.model.size))
    assert one.views.shape == (1, 6, cfg.model.size, cfg.model.size)  # what was projected, for round-trip checks
    assert one.projection.stats(one.charts)["seen"] < gen.SEEN_WARNING
    assert any("inpainted from their neighbours" in w for w in one.warnings)
    many = gen.generate(inp, "silver metal with light dust", model, cfg, steps=1, views=8, texture_size=32,
                        guard_energy=False)
    assert many.projection.stats(many.charts)["seen"] > one.projection.stats(one.charts)["seen"]


def bake_constants(folder: Path, base_color: tuple[float, float, float], metalness: float, roughness: float,
                   p: float) -> Path:
    """A baked folder of constant maps, as the add-on's Bake writes it (alpha_core = roughness^p)."""
    pbr = PbrInputs("baked", ParamMap.constant(*base_color), ParamMap.constant(roughness), ParamMap.constant(metalness))
    mat = enhance(pbr, 0, 0)
    mat.base_color = pbr.base_color
    mat.params.update(alpha_core=ParamMap.constant(roughness ** p), metalness=pbr.metalness)
    mat.settings["p"] = p
    material_folder.write(folder, mat, {"material": "baked"})
    return folder


def test_a_baked_metal_keeps_fuzz_off_and_its_base_colour(checkpoint, tmp_path):
    baked = bake_constants(tmp_path / "baked", (0.9, 0.2, 0.1), metalness=1.0, roughness=0.3, p=3.0)
    out = tmp_path / "out"
    assert main(["generate", str(GLB), "--prompt", "soft velvet", "--out", str(out), "--views", "2", "--steps", "1",
                 "--texture-size", "16", "--checkpoint", str(checkpoint), "--material", str(baked),
                 "--no-preview"]) == 0
    record = neural_folder.read(out).record
    assert record["type"] == 1 and any("metal" in w for w in record["warnings"])  # not Type 4
    assert np.allclose(read_exr(out / "base_color.exr").reshape(-1, 3), [0.9, 0.2, 0.1], atol=1e-3)


def test_a_generator_trained_for_another_encoder_is_flagged(tmp_path: Path) -> None:
    from torch_models.generator.generate import encoder_mismatch

    (tmp_path / "state.json").write_text(json.dumps({"encoder_sha256": "a" * 64}))
    assert encoder_mismatch(tmp_path, "a" * 64) is None
    warning = encoder_mismatch(tmp_path, "b" * 64)
    assert warning is not None and "aaaaaaaaaaaa" in warning and "bbbbbbbbbbbb" in warning
    (tmp_path / "state.json").write_text(json.dumps({}))
    assert encoder_mismatch(tmp_path, "b" * 64) is None  # older runs recorded nothing


def test_the_shipped_generator_matches_the_shipped_encoder() -> None:
    from torch_models.generator.generate import SHIPPED, encoder_mismatch
    from torch_models.neural import trained

    assert encoder_mismatch(SHIPPED, trained.encoder_digest()) is None
    assert json.loads((SHIPPED / "state.json").read_text())["encoder_sha256"] == trained.encoder_digest()


def test_roughness_and_metalness_come_from_the_file_or_the_bake(tmp_path):
    """glTF factors become the generator's PBR condition; a bake gives roughness back from alpha_core = r^p;
    formats without PBR leave it unknown."""
    import trimesh
    from trimesh.visual.material import PBRMaterial

    from torch_models.generator.mesh_input import load_mesh, stack_maps, use_baked_material

    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(uv=np.random.default_rng(0).random((len(box.vertices), 2)),
                                               material=PBRMaterial(roughnessFactor=0.3, metallicFactor=0.9))
    glb = tmp_path / "box.glb"
    box.export(glb)
    inp = load_mesh(glb)
    assert np.allclose(inp.materials[0].roughness_metalness.reshape(-1, 2), [0.3, 0.9], atol=1e-3) and inp.metallic
    obj = tmp_path / "box.obj"
    trimesh.creation.box().export(obj)
    bare = load_mesh(obj)
    assert bare.materials[0].roughness_metalness is None and not bare.metallic and not bare.pbr_known
    assert any("roughness" in n for n in bare.notes)

    baked = bake_constants(tmp_path / "baked", (0.5, 0.5, 0.5), metalness=0.0, roughness=0.4, p=2.5)
    use_baked_material(bare, baked)
    assert np.allclose(bare.materials[0].roughness_metalness.reshape(-1, 2), [0.4, 0.0], atol=1e-5)

    rough = np.arange(16, dtype=np.float32).reshape(4, 4, 1)
    both = stack_maps(rough, np.full((2, 2, 1), 0.5, np.float32))
    assert both.shape == (4, 4, 2) and np.array_equal(both[..., 0], rough[..., 0]) and np.all(both[..., 1] == 0.5)
    assert stack_maps(np.full((1, 1, 1), 0.2, np.float32), rough).shape == (4, 4, 2)


def test_energy_guard_darkens_only_the_texels_that_gain_energy() -> None:
    from torch_models.generator.generate import energy_guard
    from torch_models.neural import furnace, trained

    model = trained.load(trained.BASELINE)  # the MLP kind: the shipped hybrid cannot gain energy
    box = torch.rand(128, 6, generator=torch.Generator().manual_seed(0)) * 2.2 - 1.1
    check = furnace.furnace(model, box)
    gaining, bounded = box[check.failing][0], box[~check.failing][0]
    texture = torch.stack([bounded] * 15 + [gaining]).reshape(4, 4, 6).numpy()
    scale = energy_guard(texture, model)
    assert scale.shape == (4, 4) and (scale.reshape(-1)[:15] == 1).all() and 0 < scale.reshape(-1)[15] < 1
    fresh = furnace.furnace(model, torch.from_numpy(texture.reshape(-1, 6)), seed=3,
                        energy_scale=torch.from_numpy(scale.reshape(-1)))
    assert not fresh.failing.any()


def test_energy_guard_holds_the_quadrature_to_one_below_the_fits_tolerance() -> None:
    """A texel just over 1 (under the fit check's quadrature tolerance) still gains energy
    in a render: the guard darkens it until the quadrature reads 1 at most."""
    from torch_models.generator.generate import energy_guard
    from torch_models.neural import furnace, quadrature, trained
    from torch_models.neural.data import parameter_vectors

    model = trained.load(trained.BASELINE)  # the MLP kind: the shipped hybrid cannot gain energy
    with torch.no_grad():
        z = model.encoder(torch.from_numpy(parameter_vectors(256, np.random.default_rng(0))))
    sums = quadrature.half_vector_albedo(model, z)
    albedo = sums.albedo(torch.ones(len(z))).max(1).values
    pick = ((albedo > 1.0) & (albedo <= 1.0 + furnace.QUADRATURE_TOLERANCE)).nonzero(as_tuple=True)[0][:4]
    near, near_sums = z[pick], sums[pick]
    assert len(near) == 4 and not furnace.furnace(model, near, quadrature=near_sums).failing.any()  # the fit's check
    scale = torch.from_numpy(energy_guard(near.numpy()[None], model).reshape(-1))
    assert (scale < 1).all()
    assert (near_sums.albedo(scale).max(1).values <= 1.0 + 1e-6).all()


def test_a_zero_residual_gives_back_the_uplift_prior(checkpoint, monkeypatch):
    """The generator refines the enhancement rules' uplift: with nothing to add, every seen or
    inpainted texel is the prior's latent (as half floats), and islands no view saw get the
    diffuse fallback."""
    from torch_models.generator import generate as gen
    from torch_models.generator.mesh_input import load_mesh

    model, cfg = gen.load_generator(checkpoint)
    monkeypatch.setattr(model, "sample", lambda cond, *a, **k: torch.zeros_like(cond.prior))
    inp = load_mesh(GLB)
    out = gen.generate(inp, "silver metal with light dust", model, cfg, steps=1, views=4, texture_size=32,
                       guard_energy=False)
    reached = (out.projection.seen | out.projection.inpainted).numpy()
    assert reached.any() and np.abs(out.prior).max() > 0.05
    assert np.allclose(out.latents[reached], out.prior[reached], atol=2e-3)
    fallback = gen.diffuse_fallback_latent().numpy()
    assert np.allclose(out.latents[out.projection.fallback.numpy()], fallback, atol=2e-3)


def test_a_materials_latent_texture_follows_its_maps_up_to_the_guards_budget():
    from torch_models.generator import DEFAULT_TEXTURE_SIZE
    from torch_models.generator.mesh_input import MaterialInput

    def shape(base: tuple[int, int], rm: tuple[int, int] = (1, 1)) -> tuple[int, int]:
        material = MaterialInput("m", np.zeros((*base, 3), np.float32), np.zeros((*rm, 2), np.float32))
        return material.texture_shape(DEFAULT_TEXTURE_SIZE)

    assert shape((16, 16)) == (16, 16) and shape((16, 32)) == (16, 32)  # bake at the input's resolution
    assert shape((1, 1), (32, 32)) == (32, 32)  # a roughness texture counts as much as a colour one
    assert shape((1, 1)) == (DEFAULT_TEXTURE_SIZE,) * 2 and shape((2048, 1024)) == (DEFAULT_TEXTURE_SIZE, 32)
    assert shape((4, 4)) == (8, 8)


def test_guidance_defaults_to_the_prompts_types_and_an_explicit_value_wins(checkpoint, monkeypatch):
    from dataclasses import replace

    from richmat_addon.core import enhancement_types
    from torch_models.generator import generate as gen
    from torch_models.generator.mesh_input import load_mesh

    model, cfg = gen.load_generator(checkpoint)
    used = []
    monkeypatch.setattr(model, "sample", lambda cond, steps, seed, guidance, *a: used.append(guidance)
                        or torch.zeros_like(cond.prior))
    table = {0: 2.0, 1: 1.25}
    monkeypatch.setattr(enhancement_types, "TYPES", tuple(replace(t, guidance=table.get(t.index, t.guidance))
                                                          for t in enhancement_types.TYPES))
    inp = load_mesh(GLB)
    run = lambda prompt, **kw: gen.generate(inp, prompt, model, cfg, steps=1, views=2, texture_size=16,
                                            guard_energy=False, **kw)
    assert run("silver metal with light dust").guidance == 1.25  # Type 1: the table's entry
    assert run("silver metal with moderate haze").guidance == 2.0  # Type 0
    assert run("silver metal with light dust", guidance=3.0).guidance == 3.0
    assert used == [1.25, 2.0, 3.0]


def test_every_enhancement_type_has_a_guidance():
    from richmat_addon.core.enhancement_types import TYPES
    from torch_models.generator import guidance_by_type

    guidance = guidance_by_type()
    assert sorted(guidance) == [t.index for t in TYPES] and min(guidance.values()) >= 1.0


def test_a_bare_mesh_takes_the_colour_metal_and_finish_the_prompt_names(checkpoint, tmp_path):
    from richmat_addon.core.base_materials import METALS

    obj = tmp_path / "ball.obj"
    trimesh.creation.uv_sphere(radius=0.5, count=[12, 12]).export(str(obj))  # no material: 0.8 grey until now
    runs = {}
    for name, prompt, base in (("gold", "brushed gold metal with a glossy clearcoat", "auto"),
                               ("red", "red paint with heavy dust", "auto"), ("kept", "red paint", "mesh"),
                               ("spelt", "vermilion paint", "auto")):  # the survey spells it "vermillion"
        out = tmp_path / name
        assert main(["generate", str(obj), "--prompt", prompt, "--out", str(out), "--views", "2", "--steps", "1",
                     "--texture-size", "16", "--checkpoint", str(checkpoint), "--no-preview", "--base", base]) == 0
        runs[name] = (neural_folder.read(out).record, read_exr(out / "base_color.exr").reshape(-1, 3))
    record, base = runs["gold"]
    assert np.allclose(base, METALS["gold"], atol=1e-3) and record["type"] == 2
    assert record["reading"]["metalness"] == 1.0 and record["reading"]["roughness"] == pytest.approx(0.35)
    assert any("metalness 1 from the prompt's words" in n for n in record["notes"])
    record, base = runs["red"]
    assert base[0, 0] > 0.5 and base[0, 1:].max() < 0.01 and record["reading"]["strengths"] == {"dust": "heavy"}
    assert np.allclose(runs["kept"][1], 0.8, atol=1e-3)  # --base mesh: the mesh's own grey
    record, base = runs["spelt"]
    assert record["reading"]["colour_name"].startswith("vermillion (for 'vermilion'")
    assert np.allclose(base, named_colours.table()["vermillion"], atol=1e-3)


def test_strength_words_set_the_priors_dust_and_the_old_draw_stays_without_them(checkpoint):
    from torch_models.generator import generate as gen
    from torch_models.generator.procedural import make_asset
    from torch_models.generator.mesh_input import MeshInput

    model, cfg = gen.load_generator(checkpoint)
    asset = make_asset(3, 16)
    inp = MeshInput.from_pbr(asset.mesh, asset.pbr)
    kw = dict(steps=1, views=2, texture_size=16, guard_energy=False)
    priors = {w: gen.generate(inp, f"paint with {w} dust", model, cfg, **kw).prior for w in ("faint", "thick")}
    drawn = [gen.generate(inp, f"paint with {w} dust", model, cfg, strengths=False, **kw).prior
             for w in ("faint", "thick")]
    assert np.abs(priors["faint"] - priors["thick"]).mean() > 0.01
    assert np.array_equal(drawn[0], drawn[1])  # before strengths were read, the words moved no setting
