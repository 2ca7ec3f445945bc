"""Blender side, materials: read each Principled BSDF as PBR inputs, unwrap meshes without UVs.

Both use the add-on's own code (``richmat_addon.blender.pbr_source`` read
leniently, ``richmat_addon.blender.unwrap``), so the farm and the add-on see a
material the same way. Any input the reader cannot follow keeps the socket's own
value, with a note; textures larger than ``max_texture`` are downscaled (noted);
missing image files fall back to the socket value (noted), as do textures of
meshes that cannot be unwrapped.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import bpy

from richmat_addon.blender.pbr_source import InputProblem, load_pbr, read_sources
from richmat_addon.blender.unwrap import unwrap
from richmat_addon.core.maps import PbrInputs

from .bl_scene import mesh_objects

MAX_UNWRAP_FACES = 200_000  # xatlas time grows fast; bigger meshes are recorded instead
DEFAULT_MATERIAL = "richmat_default"


@dataclass
class MaterialSource:
    material: bpy.types.Material
    pbr: PbrInputs
    notes: list[str] = field(default_factory=list)


def ensure_materials() -> None:
    """Meshes without a material get one plain grey Principled material."""
    bare = [o for o in mesh_objects() if not any(s.material for s in o.material_slots)]
    if bare:
        mat = bpy.data.materials.new(DEFAULT_MATERIAL)
        for obj in bare:
            obj.data.materials.clear()
            obj.data.materials.append(mat)


def used_materials() -> list[bpy.types.Material]:
    seen: dict[str, bpy.types.Material] = {}
    for obj in mesh_objects():
        for slot in obj.material_slots:
            if slot.material is not None:
                seen.setdefault(slot.material.name, slot.material)
    return list(seen.values())


def read_pbr(mat: bpy.types.Material, max_texture: int) -> MaterialSource:
    """The add-on's reader, lenient: what it cannot follow keeps the socket's value, with a note."""
    sources = read_sources(mat, "lenient")
    pbr = load_pbr(sources, max_texture)
    return MaterialSource(mat, pbr, sources.notes)


def unwrap_missing_uvs() -> list[str]:
    """Give every mesh without UVs an xatlas atlas; say which could not get one and why."""
    notes = []
    for obj in mesh_objects():
        mesh = obj.data
        if mesh.uv_layers:
            continue
        if len(mesh.polygons) > MAX_UNWRAP_FACES:
            notes.append(f"{obj.name}: no UVs and {len(mesh.polygons)} faces (> {MAX_UNWRAP_FACES}): "
                         "not unwrapped, its materials stay untextured")
            continue
        try:
            unwrap(obj, triangulate=True)
        except InputProblem as problem:
            notes.append(f"{obj.name}: no UVs, not unwrapped: {problem}")
            continue
        notes.append(f"{obj.name}: no UVs, unwrapped with xatlas")
    return notes


def material_surfaces(mat: bpy.types.Material) -> list[tuple[bpy.types.Object, list[int]]]:
    """Every mesh object using ``mat`` and its slots holding it: together they fill its texture space."""
    surfaces = [(o, [i for i, s in enumerate(o.material_slots) if s.material == mat]) for o in mesh_objects()]
    return [(o, slots) for o, slots in surfaces if slots]
