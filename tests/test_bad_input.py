"""Texture formats and degenerate values, end to end through the enhance command.

Each case builds a one-cube GLB whose images are encoded in the format under
test, runs ``python -m torch_models enhance`` in-process and checks the written
maps numerically, or checks the one-line refusal.
"""
from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from richmat_addon.core import material_folder
from richmat_addon.core.folder_io import read_exr
from torch_models.brdf.model import LayeredBsdf
from torch_models.cli import main
from torch_models.cli_enhance import pil_decode
from tests.test_gltf_io import _Builder, cube_arrays, glb_bytes
from torch_models.assets.gltf_materials import read_materials


def encode(img: Image.Image, fmt: str = "PNG") -> bytes:
    buf = io.BytesIO()
    img.save(buf, format=fmt)
    return buf.getvalue()


def cube_glb(path: Path, base: bytes | None, mr: bytes | None, mime: str = "image/png",
             factors: dict | None = None) -> Path:
    """A UV cube with one material: base colour and metal-rough textures as given (None: absent)."""
    b = _Builder()
    pos, nrm, uv, idx = cube_arrays()
    prim = {"attributes": {"POSITION": b.accessor(pos), "NORMAL": b.accessor(nrm), "TEXCOORD_0": b.accessor(uv)},
            "indices": b.accessor(idx.reshape(-1)), "material": 0}
    images, textures, pbr = [], [], dict(factors or {})
    for key, data in (("baseColorTexture", base), ("metallicRoughnessTexture", mr)):
        if data is not None:
            images.append({"bufferView": b.view(data), "mimeType": mime})
            textures.append({"source": len(images) - 1})
            pbr[key] = {"index": len(textures) - 1}
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [prim]}], "materials": [{"name": "m", "pbrMetallicRoughness": pbr}],
           "buffers": [{"byteLength": len(b.bin)}], "bufferViews": b.views, "accessors": b.accessors}
    if images:
        doc.update(images=images, textures=textures)
    path.write_bytes(glb_bytes(doc, bytes(b.bin)))
    return path


def enhance_cube(tmp_path: Path, glb: Path, type_: str = "3") -> Path:
    out = tmp_path / "out"
    assert main(["enhance", str(glb), "--type", type_, "--seed", "1", "--out", str(out)]) == 0
    return out / "m"


def test_16_bit_roughness_is_scaled_by_65535(tmp_path: Path) -> None:
    grey = np.full((6, 10), 40000, np.uint16)  # roughness = metalness = 0.6104 in a 16-bit grey PNG
    glb = cube_glb(tmp_path / "c.glb", None, encode(Image.fromarray(grey)))
    pbr = read_materials(glb, pil_decode)[0].pbr
    assert pbr.roughness.value.max() == pytest.approx(40000 / 65535, abs=1e-5)


def test_8_bit_palette_greyscale_and_jpeg_base_colours(tmp_path: Path) -> None:
    rgb = np.zeros((8, 12, 3), np.uint8)
    rgb[..., 0], rgb[..., 1] = 200, 50
    palette = Image.fromarray(rgb).quantize(colors=4)  # an exact palette of the one colour
    grey = Image.fromarray(np.full((8, 12), 128, np.uint8))
    expect_red = ((200 / 255 + 0.055) / 1.055) ** 2.4
    for name, data, mime, red in (("palette", encode(palette), "image/png", expect_red),
                                  ("grey", encode(grey), "image/png", ((128 / 255 + 0.055) / 1.055) ** 2.4),
                                  ("jpeg", encode(Image.fromarray(rgb), "JPEG"), "image/jpeg", expect_red)):
        glb = cube_glb(tmp_path / f"{name}.glb", data, None, mime)
        base = read_materials(glb, pil_decode)[0].pbr.base_color.value
        assert base.shape[-1] == 3, name
        assert float(np.median(base[..., 0])) == pytest.approx(red, rel=0.03), name


def test_non_square_npot_maps_of_different_sizes(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    base = Image.fromarray(rng.integers(0, 255, (23, 37, 3), dtype=np.uint8))
    mr = Image.fromarray(rng.integers(0, 255, (9, 16, 3), dtype=np.uint8))
    glb = cube_glb(tmp_path / "c.glb", encode(base), encode(mr), factors={"metallicFactor": 0.0})
    folder = enhance_cube(tmp_path, glb)
    assert read_exr(folder / "base_color.exr").shape == (23, 37, 3)  # the input's own resolution
    for exr in folder.glob("*.exr"):
        value = read_exr(exr)
        assert np.isfinite(value).all(), exr.name


def test_material_without_textures_stays_constant(tmp_path: Path) -> None:
    glb = cube_glb(tmp_path / "c.glb", None, None, factors={"baseColorFactor": [0.2, 0.4, 0.6, 1.0],
                                                          "roughnessFactor": 0.7, "metallicFactor": 0.0})
    folder = enhance_cube(tmp_path, glb, "5")
    assert sorted(p.name for p in folder.glob("*.exr")) == []  # every map is a constant in params.json


@pytest.mark.parametrize("roughness", [0.0, 1.0])
@pytest.mark.parametrize("base", [(0.0, 0.0, 0.0), (1.0, 1.0, 1.0)])
@pytest.mark.parametrize("metal", [0.0, 1.0])
def test_extreme_constants_give_a_finite_energy_bounded_bsdf(tmp_path: Path, roughness: float,
                                                             base: tuple, metal: float) -> None:
    glb = cube_glb(tmp_path / "c.glb", None, None, factors={"baseColorFactor": [*base, 1.0],
                                                          "roughnessFactor": roughness, "metallicFactor": metal})
    out = tmp_path / "out"
    assert main(["enhance", str(glb), "--type", "auto", "--seed", "3", "--out", str(out)]) == 0
    record = material_folder.read(out / "m").record
    params = {k: torch.tensor([v], dtype=torch.float32) for k, v in record["constants"].items()
              if k != "base_color"}
    bsdf = LayeredBsdf(params, torch.tensor([record["constants"]["base_color"]], dtype=torch.float32))
    gen = torch.Generator().manual_seed(0)
    for mu in (1.0, 0.5, 1e-3):
        wi = torch.tensor([[math.sqrt(1 - mu * mu), 0.0, mu]]).expand(20000, 3)
        wo = bsdf.sample(wi, torch.rand(20000, 3, generator=gen))
        weight = bsdf.eval(wi, wo) / bsdf.pdf(wi, wo).clamp(min=1e-30)[:, None]
        weight = torch.where(wo[:, 2:3] > 0, weight, torch.zeros_like(weight))
        assert torch.isfinite(weight).all() and (weight >= 0).all()
        assert float(weight.mean(0).max()) <= 1.03, (mu, weight.mean(0))
