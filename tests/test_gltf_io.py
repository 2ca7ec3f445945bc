"""glTF material/geometry reading and UV rasterisation.

Runs on a small GLB written here (so a fresh clone without ../shared is covered) and,
when present, on the real sample assets, compared with the stats table of
../shared/assets/README.md. ``write_test_glb`` is also used by test_cli_enhance.py.
"""
from __future__ import annotations

import io
import json
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from richmat_addon.core.colour import srgb_to_linear
from richmat_addon.core import uv_raster
from richmat_addon.core.uv_raster import rasterize
from torch_models.assets.gltf_container import GltfError, glb_bytes, load_gltf
from torch_models.assets.gltf_materials import read_materials
from torch_models.assets.gltf_mesh import read_geometry


def pil_decode(data: bytes, mime: str) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(data)))


def counting_decoder() -> tuple[list[str], Any]:
    calls: list[str] = []

    def decode(data: bytes, mime: str) -> np.ndarray:
        calls.append(mime)
        return pil_decode(data, mime)

    return calls, decode


# --- a procedural GLB --------------------------------------------------------------

# Cube faces (glTF, +Y up): normal, and two in-plane axes. Face f is unwrapped into
# cell (f % 3, f // 3) of a 3 x 2 grid, so the cube covers its texture exactly once.
_FACES = [((1, 0, 0), (0, 1, 0), (0, 0, 1)), ((-1, 0, 0), (0, 1, 0), (0, 0, 1)),
          ((0, 1, 0), (1, 0, 0), (0, 0, 1)), ((0, -1, 0), (1, 0, 0), (0, 0, 1)),
          ((0, 0, 1), (1, 0, 0), (0, 1, 0)), ((0, 0, -1), (1, 0, 0), (0, 1, 0))]
TOP_FACE = 2  # +Y in glTF, +Z in the project's world frame


def cube_arrays() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Unit cube: positions, normals, UVs (3 x 2 atlas), triangle indices."""
    pos, nrm, uv, idx = [], [], [], []
    for f, (n, a, b) in enumerate(_FACES):
        n, a, b = map(np.asarray, (n, a, b))
        col, row = f % 3, f // 3
        for su, sv in ((0, 0), (1, 0), (1, 1), (0, 1)):
            pos.append(0.5 * n + (su - 0.5) * a + (sv - 0.5) * b)
            nrm.append(n)
            uv.append(((col + su) / 3, (row + sv) / 2))
        k = 4 * f
        idx += [(k, k + 1, k + 2), (k, k + 2, k + 3)]
    return (np.float32(pos), np.float32(nrm), np.float32(uv), np.uint16(idx))


def png(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(array).save(buf, format="PNG")
    return buf.getvalue()


def base_color_image() -> np.ndarray:
    img = np.zeros((8, 8, 3), np.uint8)
    img[..., 0] = np.arange(8)[None, :] * 32
    img[..., 1] = 128
    img[..., 2] = np.arange(8)[:, None] * 32
    return img


def orm_image() -> np.ndarray:
    """R occlusion, G roughness ramp along x, B metalness ramp along y."""
    img = np.full((8, 8, 3), 255, np.uint8)
    img[..., 1] = np.arange(8)[None, :] * 36
    img[..., 2] = np.arange(8)[:, None] * 36
    return img


class _Builder:
    """Packs arrays and images into one binary buffer with views and accessors."""

    def __init__(self) -> None:
        self.bin = bytearray()
        self.views: list[dict[str, Any]] = []
        self.accessors: list[dict[str, Any]] = []

    def view(self, data: bytes) -> int:
        self.bin += b"\0" * (-len(self.bin) % 4)
        self.views.append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)})
        self.bin += data
        return len(self.views) - 1

    def accessor(self, array: np.ndarray) -> int:
        ctype = {np.float32: 5126, np.uint8: 5121, np.uint16: 5123, np.uint32: 5125}[array.dtype.type]
        kind = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4", 16: "MAT4"}[array.shape[1] if array.ndim == 2 else 1]
        acc = {"bufferView": self.view(array.tobytes()), "componentType": ctype,
               "count": len(array), "type": kind}
        if array.dtype == np.float32:
            acc["min"], acc["max"] = (np.atleast_1d(array.min(axis=0)).tolist(),
                                      np.atleast_1d(array.max(axis=0)).tolist())
        self.accessors.append(acc)
        return len(self.accessors) - 1


def write_test_glb(path: Path, material_names: tuple[str, ...] = ("Painted", "Plain", "Tiled")) -> Path:
    """A cube (textured material 0), a triangle without UVs (factor-only material 1)
    and a second cube whose material 2 reuses the ORM image (shared decode) through a
    KHR_texture_transform. The first cube's node scales by 2: positions span [-1, 1].
    """
    b = _Builder()
    pos, nrm, uv, idx = cube_arrays()
    cube = {"attributes": {"POSITION": b.accessor(pos), "NORMAL": b.accessor(nrm),
                           "TEXCOORD_0": b.accessor(uv)},
            "indices": b.accessor(idx.reshape(-1)), "material": 0}
    tri = {"attributes": {"POSITION": b.accessor(np.float32([[0, 0, 0], [1, 0, 0], [0, 1, 0]])),
                          "NORMAL": b.accessor(np.float32([[0, 0, 1]] * 3))}, "material": 1}
    images = [{"bufferView": b.view(png(base_color_image())), "mimeType": "image/png", "name": "bc"},
              {"bufferView": b.view(png(orm_image())), "mimeType": "image/png", "name": "orm"}]
    names = list(material_names) + [f"extra{i}" for i in range(3 - len(material_names))]
    doc = {
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_texture_transform"],
        "scene": 0, "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [{"mesh": 0, "scale": [2, 2, 2]}, {"mesh": 1, "translation": [0, 3, 0]},
                  {"mesh": 2, "translation": [3, 0, 0]}],
        "meshes": [{"primitives": [cube]}, {"primitives": [tri]}, {"primitives": [dict(cube, material=2)]}],
        "materials": [
            {"name": names[0], "pbrMetallicRoughness": {
                "baseColorTexture": {"index": 0}, "baseColorFactor": [1.0, 0.5, 1.0, 1.0],
                "metallicRoughnessTexture": {"index": 1}, "roughnessFactor": 0.5}},
            {"name": names[1], "pbrMetallicRoughness": {
                "baseColorFactor": [0.8, 0.0, 0.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.3}},
            {"name": names[2], "pbrMetallicRoughness": {
                "metallicRoughnessTexture": {"index": 1, "extensions": {
                    "KHR_texture_transform": {"scale": [4.0, 4.0], "offset": [0.5, 0.0]}}}}},
        ],
        "textures": [{"source": 0}, {"source": 1}],
        "images": images,
        "buffers": [{"byteLength": len(b.bin)}],
        "bufferViews": b.views,
        "accessors": b.accessors,
    }
    path.write_bytes(glb_bytes(doc, bytes(b.bin)))
    return path


@pytest.fixture
def test_glb(tmp_path: Path) -> Path:
    return write_test_glb(tmp_path / "cube.glb")


# --- materials ---------------------------------------------------------------------

def test_procedural_materials(test_glb: Path) -> None:
    calls, decode = counting_decoder()
    painted, plain, tiled = read_materials(test_glb, decode)
    assert len(calls) == 2, "each image is decoded once, the shared ORM included"

    bc = base_color_image() / 255.0
    expected_bc = srgb_to_linear(bc) * np.float32([1.0, 0.5, 1.0])
    np.testing.assert_allclose(painted.pbr.base_color.value, expected_bc, atol=1e-6)
    orm = orm_image() / 255.0
    np.testing.assert_allclose(painted.pbr.roughness.value[..., 0], orm[..., 1] * 0.5, atol=1e-6)
    np.testing.assert_allclose(painted.pbr.metalness.value[..., 0], orm[..., 2], atol=1e-6)
    assert painted.resolution == (8, 8)

    assert plain.pbr.base_color.is_constant and plain.pbr.roughness.is_constant
    assert plain.pbr.metalness.is_constant and plain.resolution is None
    np.testing.assert_allclose(plain.pbr.base_color.value, [0.8, 0.0, 0.0])
    np.testing.assert_allclose(plain.pbr.roughness.value, [0.3], atol=1e-7)

    transform = tiled.placement.transform
    assert transform is not None and transform.scale == (4.0, 4.0) and transform.offset == (0.5, 0.0)
    assert tiled.pbr.base_color.is_constant and np.allclose(tiled.pbr.base_color.value, 1.0)
    np.testing.assert_allclose(transform.apply(np.float32([[0.25, 0.5]])), [[1.5, 2.0]])


def test_geometry_world_space(test_glb: Path) -> None:
    geo = read_geometry(load_gltf(test_glb))
    cube, tri = geo[0], geo[1]
    assert cube.indices.shape == (12, 3) and cube.uvs is not None
    np.testing.assert_allclose(cube.positions.min(axis=0), -1.0)  # node scale 2
    np.testing.assert_allclose(np.linalg.norm(cube.normals, axis=1), 1.0, atol=1e-6)
    assert tri.uvs is None
    # glTF +Y translation 3 becomes +Z 3 in the Z-up world frame.
    np.testing.assert_allclose(tri.positions[0], [0.0, 0.0, 3.0], atol=1e-6)


@pytest.mark.parametrize("mutate, message", [
    (lambda raw: raw[: len(raw) - 100], "truncated"),
    (lambda raw: raw[:4] + struct.pack("<I", 1) + raw[8:], "unsupported GLB container version 1"),
    (lambda raw: b"not a gltf file at all", "not a glTF file"),
    (lambda raw: raw.replace(b'"version": "2.0"', b'"version": "1.0"'), "unsupported glTF version"),
])
def test_corrupt_files_raise_clear_errors(test_glb: Path, mutate: Any, message: str) -> None:
    bad = test_glb.with_name("bad.glb")
    bad.write_bytes(mutate(test_glb.read_bytes()))
    with pytest.raises(GltfError, match=message) as err:
        read_materials(bad, pil_decode)
    assert str(bad) in str(err.value) and isinstance(err.value, ValueError)


def test_missing_external_image(tmp_path: Path) -> None:
    gltf = tmp_path / "external.gltf"
    gltf.write_text(json.dumps({
        "asset": {"version": "2.0"},
        "materials": [{"name": "m", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0}], "images": [{"uri": "textures/missing%20file.png"}]}))
    with pytest.raises(GltfError, match=r"missing%20file.png.*which is missing"):
        read_materials(gltf, pil_decode)


def test_undecodable_image_names_the_image(test_glb: Path) -> None:
    def broken(data: bytes, mime: str) -> np.ndarray:
        raise OSError("decoder exploded")

    with pytest.raises(GltfError, match=r"images\[0\] \(bc\) cannot be decoded"):
        read_materials(test_glb, broken)


# --- rasteriser --------------------------------------------------------------------

def test_raster_cube_full_coverage_and_up_normals() -> None:
    pos, nrm, uv, idx = cube_arrays()
    h, w = 48, 60
    raster, reason = rasterize(pos, nrm, uv, idx.astype(np.int64), (h, w))
    assert reason is None and raster is not None
    assert raster.coverage.all()
    np.testing.assert_allclose(np.linalg.norm(raster.normals, axis=2), 1.0, atol=1e-5)
    # Top face (cell col 2, row 0): v = 0 is the first image row in glTF.
    top = raster.normals[: h // 2, 2 * w // 3:]
    np.testing.assert_allclose(top, np.broadcast_to([0.0, 1.0, 0.0], top.shape), atol=1e-6)
    assert np.allclose(raster.positions[: h // 2, 2 * w // 3:, 1], 0.5)


def test_raster_quad_padding_and_refusals() -> None:
    pos = np.float32([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    nrm = np.float32([[0, 0, 1]] * 4)
    idx = np.int64([[0, 1, 2], [0, 2, 3]])
    half = np.float32([[0, 0], [0.5, 0], [0.5, 1], [0, 1]])  # left half of the texture
    raster, _ = rasterize(pos, nrm, half, idx, (16, 16), padding=3)
    assert raster.coverage[:, :8].all() and not raster.coverage[:, 8:].any()
    assert raster.filled[:, :11].all() and not raster.filled[:, 11:].any()
    np.testing.assert_allclose(raster.normals[:, :11], np.broadcast_to([0, 0, 1.0], (16, 11, 3)))
    assert not raster.normals[:, 11:].any()

    assert rasterize(pos, nrm, None, idx, (8, 8)) == (None, "the mesh has no UVs")
    tiled, reason = rasterize(pos, nrm, half * 8, idx, (8, 8))
    assert tiled is None and "tiled" in reason


# --- the real sample assets --------------------------------------------------------

# README "mr stats": (metallic, roughness) texel means per material.
README_MR = {
    "WaterBottle.glb": {"BottleMat": (0.63, 0.61)},
    "Avocado.glb": {"2256_Avocado_d": (0.02, 0.86)},
    "BoomBox.glb": {"BoomBox_Mat": (0.06, 0.17)},
    "Suzanne.glb": {"Suzanne": (0.98, 0.32)},
    "SheenCloth.glb": {"SheenClothMat": (0.00, 0.67)},
    "wooden_table_02_1k.glb": {"wooden_table_02": (0.01, 0.40)},
    "NormalTangentTest.glb": {"material_0": (0.34, 0.13)},
    "FlightHelmet.glb": {"MetalPartsMat": (0.67, 0.53), "LeatherPartsMat": (0.00, 0.49),
                         "GlassPlasticMat": (0.00, 0.43), "RubberWoodMat": (0.07, 0.49),
                         "HoseMat": (0.07, 0.49), "LensesMat": (0.00, 0.24)},
}


@pytest.mark.parametrize("asset", sorted(README_MR))
def test_real_mr_stats_match_readme(shared_assets: Path, asset: str) -> None:
    mats = {m.pbr.name: m for m in read_materials(shared_assets / "models" / asset, pil_decode)}
    for name, (metal, rough) in README_MR[asset].items():
        pbr = mats[name].pbr
        assert pbr.metalness.mean()[0] == pytest.approx(metal, abs=0.006), name
        assert pbr.roughness.mean()[0] == pytest.approx(rough, abs=0.006), name
        assert not pbr.base_color.is_constant and not pbr.roughness.is_constant


def test_real_factor_only_materials(shared_assets: Path) -> None:
    (box,) = read_materials(shared_assets / "models" / "Box.glb", pil_decode)
    assert all(m.is_constant for m in (box.pbr.base_color, box.pbr.roughness, box.pbr.metalness))
    np.testing.assert_allclose(box.pbr.base_color.value, [0.8, 0.0, 0.0], atol=1e-6)
    assert box.pbr.metalness.value[0] == 0.0 and box.pbr.roughness.value[0] == 1.0  # glTF default

    calls, decode = counting_decoder()
    truck = {m.pbr.name: m.pbr for m in read_materials(shared_assets / "models" / "CesiumMilkTruck.glb", decode)}
    assert len(calls) == 1, "truck and wheels share one image"
    for name in ("glass", "window_trim"):
        assert truck[name].base_color.is_constant and truck[name].roughness.is_constant
    assert not truck["truck"].base_color.is_constant and truck["truck"].metalness.is_constant

    geo = read_geometry(load_gltf(shared_assets / "models" / "CesiumMilkTruck.glb"))
    assert geo[0].uvs is not None and geo[1].uvs is None and geo[2].uvs is None


def test_real_texture_transform_recorded(shared_assets: Path) -> None:
    (cloth,) = read_materials(shared_assets / "models" / "SheenCloth.glb", pil_decode)
    assert cloth.placement.transform.scale == (30.0, -30.0)
    assert cloth.textures["normal"].transform.scale == (30.0, -30.0)


class _CountingNumpy:
    """numpy for uv_raster, counting the masks it scans with ``nonzero``: its per-texel work."""

    def __init__(self) -> None:
        self.calls = 0
        self.texels = 0

    def __getattr__(self, name: str) -> Any:
        return getattr(np, name)

    def nonzero(self, mask: np.ndarray) -> tuple[np.ndarray, ...]:
        self.calls += 1
        self.texels += mask.size
        return np.nonzero(mask)


def test_real_flight_helmet_raster_cost(shared_assets: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The rasteriser's cost follows the texture, not the triangles: counted in texels tested and in
    vectorised passes (seconds on a shared machine would measure its neighbours)."""
    doc = load_gltf(shared_assets / "models" / "FlightHelmet.glb")
    geo = read_geometry(doc)
    triangles = sum(len(g.indices) for g in geo.values())
    assert triangles == 94722
    counting = _CountingNumpy()
    monkeypatch.setattr(uv_raster, "np", counting)
    coverage = []
    for g in geo.values():
        texels_before = counting.texels
        raster, reason = rasterize(g.positions, g.normals, g.uvs, g.indices, (512, 512))
        assert reason is None
        # 4 dilation rings scan the whole map; the triangles' texel boxes (power-of-two tiles) the rest
        assert counting.texels - texels_before <= 8 * 512 * 512
        coverage.append(raster.coverage.mean())
        filled = raster.filled
        np.testing.assert_allclose(np.linalg.norm(raster.normals[filled], axis=1), 1.0, atol=1e-4)
    assert counting.calls < triangles // 100  # batched passes, never a pass per triangle
    assert min(coverage) > 0.1
