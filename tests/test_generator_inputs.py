"""`generate` on real-asset inputs, tiny meshes made here: several parts and materials, mirrored UVs,
a part without UVs, a tiled material; every material keeps its UVs and maps, views cover the surface,
and each material gets its own neural folder."""
import json
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
from PIL import Image

from richmat_addon.core import neural_folder
from richmat_addon.core.colour import srgb_to_linear
from richmat_addon.core.folder_io import read_exr
from torch_models.cli import main
from torch_models.cli_generate import PREVIEW_FRAMES, PREVIEW_SIZE, RUN_RECORD
from torch_models.generator import generate as gen
from torch_models.generator.mesh_input import load_mesh
from torch_models.generator.views import orbit_cameras
from tests.test_generator_generate import checkpoint  # noqa: F401  (tiny trained generator, module fixture)
from tests.test_gltf_io import _Builder, png
from torch_models.assets.gltf_container import glb_bytes

torch.set_num_threads(1)
# a base colour texture wider than tall, red on the left and blue on the right: its mean is purple
COLOUR = np.zeros((8, 16, 3), np.uint8)
COLOUR[:, :8] = (230, 20, 20)
COLOUR[:, 8:] = (20, 20, 230)
ROUGH_METAL = np.zeros((8, 16, 3), np.uint8)
ROUGH_METAL[..., 1] = np.linspace(0, 255, 16, dtype=np.uint8)  # roughness rises left to right
ROUGH_METAL[..., 2] = 51  # metalness 0.2


class _Glb(_Builder):
    """test_gltf_io's buffer packer, with primitives and a document."""

    def primitive(self, positions: np.ndarray, faces: np.ndarray, uvs: np.ndarray | None, material: int) -> dict:
        normals = np.zeros_like(positions)
        for tri in faces:  # area-weighted vertex normals
            normals[tri] += np.cross(positions[tri[1]] - positions[tri[0]], positions[tri[2]] - positions[tri[0]])
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        attributes = {"POSITION": self.accessor(positions.astype(np.float32)),
                      "NORMAL": self.accessor(normals.astype(np.float32))}
        if uvs is not None:
            attributes["TEXCOORD_0"] = self.accessor(uvs.astype(np.float32))
        return {"attributes": attributes, "indices": self.accessor(faces.reshape(-1).astype(np.uint32)),
                "material": material}

    def write(self, path: Path, doc: dict) -> Path:
        images = [{"bufferView": self.view(png(a)), "mimeType": "image/png"} for a in (COLOUR, ROUGH_METAL)]
        doc = {"asset": {"version": "2.0"}, "scene": 0, "textures": [{"source": 0}, {"source": 1}],
               "images": images, **doc, "buffers": [{"byteLength": len(self.bin)}], "bufferViews": self.views,
               "accessors": self.accessors}
        path.write_bytes(glb_bytes(doc, bytes(self.bin)))
        return path


def _box() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A box with its own UV cell per face (3 x 2 cells), seams split: (positions, faces, uvs)."""
    box = trimesh.creation.box()
    positions, faces, uvs = [], [], []
    for f, normal in enumerate(np.concatenate([np.eye(3), -np.eye(3)])):
        corners = box.vertices[box.faces[np.isclose(box.face_normals, normal).all(1)]].reshape(-1, 3)
        local = corners[:, np.abs(normal) < 0.5] + 0.5  # in [0, 1] on this face
        faces.append(np.arange(len(corners)).reshape(-1, 3) + sum(len(p) for p in positions))
        positions.append(corners)
        uvs.append((np.array([f % 3, f // 3]) + 0.1 + 0.8 * local) / [3, 2])
    return np.concatenate(positions), np.concatenate(faces), np.concatenate(uvs)


def _mirrored_strip() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A strip whose right half uses the left half's UVs mirrored: (positions, faces, uvs)."""
    xs = np.array([0.0, 1.0, 2.0])
    positions = np.array([[x, y, 0.0] for y in (0.0, 1.0) for x in xs])
    uvs = np.array([[0.1 + 0.8 * (1 - abs(x - 1)), 0.1 + 0.8 * y] for y in (0.0, 1.0) for x in xs])
    faces = np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]])
    return positions, faces, uvs


def write_parts(path: Path) -> Path:
    """Two nodes, three materials: a textured box (material 0) whose mesh also holds a mirrored strip
    (material 1, a second primitive); a tetrahedron without UVs (material 2, factors only)."""
    glb = _Glb()
    box = glb.primitive(*_box(), material=0)
    strip_positions, strip_faces, strip_uvs = _mirrored_strip()
    strip = glb.primitive(strip_positions * 0.5 + [-0.5, -0.25, 0.8], strip_faces, strip_uvs, material=1)
    tetra = glb.primitive(np.array([[0.0, 0, 0], [0.6, 0, 0], [0, 0.6, 0], [0, 0, 0.6]]),
                          np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]), None, material=2)
    doc = {"scenes": [{"nodes": [0, 1]}], "nodes": [{"mesh": 0}, {"mesh": 1, "translation": [1.2, 0, 0]}],
           "meshes": [{"primitives": [box, strip]}, {"primitives": [tetra]}],
           "materials": [
               {"name": "painted", "pbrMetallicRoughness": {
                   "baseColorTexture": {"index": 0}, "baseColorFactor": [1.0, 0.5, 1.0, 1.0],
                   "metallicRoughnessTexture": {"index": 1}, "roughnessFactor": 0.5}},
               {"name": "mirrored", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}},
               {"name": "bare", "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.6, 0.2, 1.0],
                                                         "metallicFactor": 1.0, "roughnessFactor": 0.3}}]}
    return glb.write(path, doc)


def write_tiled(path: Path) -> Path:
    """A box whose base colour is tiled 3 x 3 by KHR_texture_transform (its texture space covered 9 times)."""
    glb = _Glb()
    tiled = {"index": 0, "extensions": {"KHR_texture_transform": {"scale": [3.0, 3.0]}}}
    doc = {"extensionsUsed": ["KHR_texture_transform"], "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [glb.primitive(*_box(), material=0)]}],
           "materials": [{"name": "tiled", "pbrMetallicRoughness": {"baseColorTexture": tiled}}]}
    return glb.write(path, doc)


@pytest.fixture
def parts(tmp_path: Path) -> Path:
    return write_parts(tmp_path / "parts.glb")


def test_every_material_keeps_its_uvs_and_its_maps(parts: Path):
    inp = load_mesh(parts)
    painted, mirrored, bare = inp.materials
    assert [m.name for m in inp.materials] == ["painted", "mirrored", "bare"]
    faces = inp.mesh.materials
    box_positions, box_faces, box_uvs = _box()
    np.testing.assert_allclose(inp.mesh.uvs[inp.mesh.faces[faces == 0]], box_uvs[box_faces], atol=1e-6)  # kept
    strip_uvs = _mirrored_strip()
    np.testing.assert_allclose(inp.mesh.uvs[inp.mesh.faces[faces == 1]], strip_uvs[2][strip_uvs[1]], atol=1e-6)
    # factor times texture, sRGB decoded: the red and blue halves reach the map, not their purple mean
    expected = srgb_to_linear(COLOUR / 255.0) * np.float32([1.0, 0.5, 1.0])
    np.testing.assert_allclose(painted.base_color, expected, atol=1e-5)
    rough = ROUGH_METAL[..., 1] / 255.0 * 0.5
    np.testing.assert_allclose(painted.roughness_metalness[..., 0], rough, atol=1e-5)
    np.testing.assert_allclose(painted.roughness_metalness[..., 1], 0.2, atol=1e-2)
    assert not painted.unwrapped and painted.record == {"material_index": 0, "uv_set": 0}
    assert np.allclose(mirrored.roughness_metalness[..., 1], 0.0)
    # the part without UVs, and only it, is unwrapped; its constant maps stay as the factors say
    assert bare.unwrapped and not mirrored.unwrapped and bare.metallic and not inp.metallic
    assert np.allclose(bare.base_color.reshape(-1), [0.2, 0.6, 0.2]) and np.allclose(
        bare.roughness_metalness.reshape(-1), [0.3, 1.0])
    assert [n for n in inp.notes if "xatlas" in n] == ["material 'bare': no UVs: unwrapped with xatlas"]
    uvs = inp.mesh.uvs[inp.mesh.faces[faces == 2]]
    assert uvs.min() >= 0 and uvs.max() <= 1
    # the mirrored halves share their texels, and the user is told
    (warning,) = inp.warnings
    assert warning.startswith("material 'mirrored': its UVs overlap") and "mirrored halves" in warning
    assert painted.texture_shape(64) == (8, 16) and bare.texture_shape(64) == (64, 64)


def test_a_tiled_material_is_baked_into_its_own_uvs(tmp_path: Path):
    inp = load_mesh(write_tiled(tmp_path / "tiled.glb"))
    (tiled,) = inp.materials
    box_positions, box_faces, box_uvs = _box()
    np.testing.assert_allclose(inp.mesh.uvs[inp.mesh.faces], box_uvs[box_faces], atol=1e-6)  # the file's UVs
    assert not tiled.unwrapped and "texture_transform" not in tiled.record
    assert tiled.base_color.shape == (8, 16, 3)
    assert any("tiled or stacked" in n and "the file's own UVs" in n for n in inp.notes)
    # each face shows three tiles: read at that footprint, the red and blue halves blend
    linear = srgb_to_linear(COLOUR / 255.0)
    covered = tiled.base_color[2:6, 1:5]  # inside the first face's UV cell
    assert np.allclose(covered.mean((0, 1)), linear.mean((0, 1)), atol=0.15)


def test_views_are_chosen_to_see_more_of_the_surface_than_the_orbit(parts: Path, checkpoint: Path):  # noqa: F811
    model, cfg = gen.load_generator(checkpoint)
    inp = load_mesh(parts)
    orbit = gen.generate(inp, "red paint", model, cfg, steps=1, texture_size=16, guard_energy=False,
                         cameras=orbit_cameras(6, cfg.model.size))
    chosen = gen.generate(inp, "red paint", model, cfg, steps=1, views=6, texture_size=16, guard_energy=False)
    seen = chosen.coverage()["seen"]
    assert seen > orbit.coverage()["seen"] and seen > 0.6
    trained = orbit_cameras(cfg.corpus.views, cfg.model.size).camera_to_world  # the views the model knows come first
    assert torch.allclose(chosen.cameras.camera_to_world[:cfg.corpus.views], trained)
    counts = [int(m.charts.sum()) for m in chosen.materials]
    assert seen == pytest.approx(sum(m.stats()["seen"] * c for m, c in zip(chosen.materials, counts)) / sum(counts))
    elevation = chosen.cameras.origins[:, 2] / chosen.cameras.origins.norm(dim=-1)
    assert float(elevation.abs().max()) > 0.8  # a view from above or below, which the orbit never has
    for m in chosen.materials:  # inpainting fills only what no view saw
        assert not bool((m.projection.seen & m.projection.inpainted).any())


def test_generate_writes_a_neural_folder_per_material(parts: Path, checkpoint: Path, tmp_path: Path):  # noqa: F811
    out = tmp_path / "out"
    assert main(["generate", str(parts), "--prompt", "red paint with light dust", "--out", str(out),
                 "--views", "3", "--steps", "1", "--texture-size", "16", "--checkpoint", str(checkpoint),
                 "--no-energy-guard"]) == 0
    run = json.loads((out / RUN_RECORD).read_text())
    assert [m["material_name"] for m in run["materials"]] == ["painted", "mirrored", "bare"]
    assert run["coverage"]["seen"] > 0 and any("mirrored halves" in w for w in run["warnings"])
    for material in run["materials"]:
        record = neural_folder.read(out / material["folder"]).record
        assert record["material_name"] == material["material_name"] and record["prompt"] == run["prompt"]
        share = record["projection"]
        assert share["seen"] + share["inpainted"] + share["fallback"] == pytest.approx(1.0)
    painted = out / "materials" / "painted"
    assert read_exr(painted / "latent_0.exr").shape == (8, 16, 3)  # the input's resolution
    assert read_exr(out / "materials" / "bare" / "latent_1.exr").shape == (16, 16, 3)  # constant maps: the cap
    red_and_blue = read_exr(painted / "base_color.exr")
    assert red_and_blue[:, :8, 0].min() > 0.5 and red_and_blue[:, 8:, 2].min() > 0.5  # the texture, not its mean
    unwrapped = trimesh.load(out / "mesh.glb")  # the bare part's new UVs, beside the others' own
    assert sorted(unwrapped.geometry) == ["bare", "mirrored", "painted"]
    with Image.open(out / "preview.png") as im:
        assert im.size == (PREVIEW_FRAMES * PREVIEW_SIZE, PREVIEW_SIZE) and im.size[0] >= 512
