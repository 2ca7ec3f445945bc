"""A user's mesh file as the generator needs it: Z up, in the unit cube, with UVs and a base colour.

trimesh reads GLB/glTF/OBJ/PLY/STL. These formats are Y up, and Blender (hence
batch) turns them Z up on import: (x, y, z) -> (x, -z, y), done here too. The
mesh is centred and scaled into [-0.5, 0.5]^3 as batch's prepare stage does. A
single textured part keeps its UVs and base colour texture; otherwise the parts
are merged, unwrapped with xatlas and given the mean of their base colour
factors (noted).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from richmat_addon.core.gltf_materials import srgb_to_linear

from .views import Mesh


@dataclass
class MeshInput:
    mesh: Mesh
    base_color: np.ndarray  # (H, W, 3) linear, or (1, 1, 3) for a constant
    had_uvs: bool
    notes: list[str] = field(default_factory=list)
    metallic: bool = False  # known from a baked material (use_baked_material); mesh files do not say


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


def load_mesh(path: Path) -> MeshInput:
    import trimesh
    import xatlas

    scene = trimesh.load(str(path), force="scene")
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
    return MeshInput(mesh, base.astype(np.float32), had_uvs, notes)


def use_baked_material(inp: MeshInput, folder: Path) -> None:
    """Take the base colour and metalness of a baked enhanced-material folder (params.json).

    The add-on bakes the material it previews; generating against that same base
    colour keeps the latents and the preview's diffuse base in agreement, and its
    metalness lets the prompt's type follow the enhancer's rule for metals."""
    import json

    from richmat_addon.core.enhance import METALLIC_THRESHOLD
    from ..neural.fit import read_exr

    params_file = folder / "params.json"
    if not params_file.is_file():
        raise ValueError(f"{folder}: not a baked material folder (no params.json)")
    params = json.loads(params_file.read_text())

    def value(name: str) -> np.ndarray:
        if name in params["textures"]:
            return read_exr(folder / params["textures"][name])
        return np.asarray(params["constants"][name], np.float32).reshape(1, 1, -1)

    inp.base_color = value("base_color")[..., :3]
    inp.metallic = float(value("metalness")[..., 0].mean()) > METALLIC_THRESHOLD
