"""A user's mesh file as the generator needs it: Z up, in the unit cube, with UVs, a base colour and,
where the file has them, roughness and metalness.

trimesh reads GLB/glTF/OBJ/PLY/STL. These formats are Y up, and Blender (hence
batch) turns them Z up on import: (x, y, z) -> (x, -z, y), done here too. The
mesh is centred and scaled into [-0.5, 0.5]^3 as batch's prepare stage does. A
single textured part keeps its UVs and base colour texture; otherwise the parts
are merged, unwrapped with xatlas and given the mean of their base colour
factors (noted). A glTF material's roughness and metalness (factors times the
metallicRoughness texture's G and B) condition the generator too; formats without
them (OBJ, PLY) leave them unknown, which the generator was trained to handle.
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from richmat_addon.core.enhance import METALLIC_THRESHOLD, is_metallic
from richmat_addon.core.colour import srgb_to_linear
from richmat_addon.core.gltf_materials import read_uri
from richmat_addon.core.maps import PbrInputs

from .views import Mesh


@dataclass
class MeshInput:
    mesh: Mesh
    base_color: np.ndarray  # (H, W, 3) linear, or (1, 1, 3) for a constant
    had_uvs: bool
    notes: list[str] = field(default_factory=list)
    metallic: bool = False  # whether the enhancer's metal rules apply (known with the PBR maps)
    roughness_metalness: np.ndarray | None = None  # (H, W, 2) or (1, 1, 2); None where unknown

    @classmethod
    def from_pbr(cls, mesh: Mesh, pbr: PbrInputs, had_uvs: bool = True) -> "MeshInput":
        """A mesh whose full PBR material is known (procedural objects, the demo)."""
        return cls(mesh, pbr.base_color.value.reshape(_image_shape(pbr.base_color.value)), had_uvs,
                   metallic=is_metallic(pbr), roughness_metalness=roughness_metalness(pbr))


def _image_shape(value: np.ndarray) -> tuple[int, int, int]:
    """A parameter map's value as an (H, W, C) image; constants are 1 x 1."""
    return value.shape if value.ndim == 3 else (1, 1, value.shape[-1])


def resize_nearest(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """(h, w, C) image at ``size`` by nearest texel; a (1, 1, C) constant stays constant."""
    if image.shape[:2] in (size, (1, 1)):
        return image
    rows = np.arange(size[0]) * image.shape[0] // size[0]
    cols = np.arange(size[1]) * image.shape[1] // size[1]
    return image[rows][:, cols]


def stack_maps(roughness: np.ndarray, metalness: np.ndarray) -> np.ndarray:
    """(H, W, 2) from two single-channel images (H, W, 1) or (1, 1, 1); a smaller texture is
    resampled (nearest) to the larger one's size."""
    size = max((m.shape[:2] for m in (roughness, metalness)), key=lambda s: s[0] * s[1])
    resized = [np.broadcast_to(resize_nearest(m, size), (*size, 1)) for m in (roughness, metalness)]
    return np.concatenate(resized, -1).astype(np.float32)


def roughness_metalness(pbr: PbrInputs) -> np.ndarray:
    """The generator's roughness and metalness condition of a PBR material."""
    return stack_maps(*(m.value.reshape(_image_shape(m.value))[..., :1] for m in (pbr.roughness, pbr.metalness)))


def _roughness_metalness(part) -> np.ndarray | None:  # part: trimesh.Trimesh
    """A glTF part's roughness and metalness (H, W, 2) or (1, 1, 2); None for materials without them."""
    material = getattr(part.visual, "material", None)
    if material is None or not hasattr(material, "metallicRoughnessTexture"):
        return None  # not a PBR (glTF) material
    factors = [1.0 if f is None else float(f) for f in (material.roughnessFactor, material.metallicFactor)]
    image = material.metallicRoughnessTexture
    if image is None:
        return np.asarray(factors, np.float32).reshape(1, 1, 2)
    texels = np.asarray(image.convert("RGB"), np.float32) / 255.0  # linear data, not sRGB
    return (texels[..., 1:3] * np.asarray(factors, np.float32)).astype(np.float32)


def _base_colour(part) -> tuple[np.ndarray, np.ndarray | None]:  # part: trimesh.Trimesh
    """(factor (3,) linear, texture (H, W, 3) linear or None) of a part's material."""
    material = getattr(part.visual, "material", None)
    factor = np.ones(3)
    texture = None
    if material is not None:
        if getattr(material, "baseColorFactor", None) is not None:
            factor = np.asarray(material.baseColorFactor[:3], np.float64) / 255.0
        image = getattr(material, "baseColorTexture", None) or getattr(material, "image", None)
        if image is not None:
            texture = srgb_to_linear(np.asarray(image.convert("RGB"), np.float64) / 255.0)
    else:
        factor = np.full(3, 0.8)
    return factor, texture


class _MeshFolder(Mapping[str, bytes]):
    """trimesh's resolver for the files a mesh refers to (glTF buffers and images, OBJ
    materials and textures): each is read by ``read_uri``, so a crafted file reads
    nothing outside its folder and nothing over the size cap."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __getitem__(self, name: str) -> bytes:
        return read_uri(self.path, name, "the mesh file")

    def __iter__(self) -> Iterator[str]:  # the folder is not listed: only named files are read
        return iter(())

    def __len__(self) -> int:
        return 0


def load_mesh(path: Path) -> MeshInput:
    import trimesh
    import xatlas

    scene = trimesh.load(str(path), force="scene", resolver=_MeshFolder(Path(path)))
    parts = [g for g in scene.dump() if isinstance(g, trimesh.Trimesh) and len(g.faces)]
    if not parts:
        raise ValueError(f"{path}: no triangles")
    notes: list[str] = []
    merged = parts[0] if len(parts) == 1 else trimesh.util.concatenate(parts)
    v = np.asarray(merged.vertices, np.float64)
    v = np.stack([v[:, 0], -v[:, 2], v[:, 1]], 1)
    v -= (v.max(0) + v.min(0)) / 2
    v /= max((v.max(0) - v.min(0)).max(), 1e-12)
    n = np.asarray(merged.vertex_normals, np.float64)
    n = np.stack([n[:, 0], -n[:, 2], n[:, 1]], 1)
    faces = np.asarray(merged.faces, np.int64)
    uv = getattr(merged.visual, "uv", None) if len(parts) == 1 else None
    factor, texture = _base_colour(parts[0]) if len(parts) == 1 else (None, None)
    if uv is not None and len(uv) == len(v):
        uv = np.asarray(uv, np.float32).copy()
        uv[:, 1] = 1.0 - uv[:, 1]  # trimesh keeps v up; views.py counts v down (glTF)
        mesh = Mesh(v.astype(np.float32), n.astype(np.float32), uv, faces)
        had_uvs = True
    else:
        vmap, new_faces, new_uv = xatlas.parametrize(v.astype(np.float32), faces.astype(np.uint32))
        mesh = Mesh(v[vmap].astype(np.float32), n[vmap].astype(np.float32), new_uv.astype(np.float32),
                    new_faces.astype(np.int64))
        had_uvs = False
        notes.append("the mesh had no usable UVs: unwrapped with xatlas")
    if factor is None:
        factor = np.mean([_base_colour(p)[0] for p in parts], 0)
        notes.append(f"{len(parts)} parts merged; base colour = the mean of their base colour factors")
    base = (factor[None, None] * texture if texture is not None and had_uvs else factor[None, None])
    pbr = _roughness_metalness(parts[0]) if len(parts) == 1 else None
    if pbr is not None and not had_uvs:
        pbr = pbr.reshape(-1, 2).mean(0).reshape(1, 1, 2)  # its texture no longer fits the new UVs
    if pbr is None:
        notes.append("no roughness or metalness in the file: the generator goes by the prompt alone")
    metallic = pbr is not None and float(pbr[..., 1].mean()) > METALLIC_THRESHOLD
    return MeshInput(mesh, base.astype(np.float32), had_uvs, notes, metallic, pbr)


def use_baked_material(inp: MeshInput, folder: Path) -> None:
    """Take the base colour, roughness and metalness of a baked enhanced-material folder (params.json).

    The add-on bakes the material it previews; generating against that same base
    colour keeps the latents and the preview's diffuse base in agreement, and its
    metalness lets the prompt's type follow the enhancer's rule for metals."""
    from richmat_addon.core import material_folder
    from richmat_addon.core.folder_io import FormatError

    baked = material_folder.read(folder)

    def value(name: str) -> np.ndarray:
        pmap = baked.map(name)
        return pmap.value.reshape(1, 1, -1) if pmap.is_constant else pmap.value

    inp.base_color = value("base_color")[..., :3]
    inp.metallic = float(value("metalness")[..., 0].mean()) > METALLIC_THRESHOLD
    exponent = baked.record["settings"].get("p")
    if exponent is None:
        raise FormatError(f"{folder}: params.json has no settings.p (roughness exponent); bake the material again")
    roughness = value("alpha_core")[..., :1] ** (1.0 / exponent)  # enhance: alpha_core = roughness^p
    inp.roughness_metalness = stack_maps(roughness, value("metalness")[..., :1])
