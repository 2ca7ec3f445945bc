"""Blender side, materials: read each Principled BSDF as PBR inputs, unwrap meshes without UVs.

Follows what importers build: an Image Texture into Base Color / Roughness /
Metallic, directly or through Separate Color (glTF's packed metal-rough). Any
other input graph keeps the socket's own value, with a note. Textures larger
than ``max_texture`` are downscaled (noted); missing image files fall back to
the socket value (noted), as do textures of meshes that cannot be unwrapped.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import bmesh
import bpy
import numpy as np

from richmat_addon.core.gltf_materials import srgb_to_linear
from richmat_addon.core.maps import ParamMap, PbrInputs

from .bl_scene import mesh_objects

MAX_UNWRAP_FACES = 200_000  # xatlas time grows fast; bigger meshes are recorded instead
DEFAULT_MATERIAL = "richmat_default"
_CHANNEL = {"Red": 0, "Green": 1, "Blue": 2, "R": 0, "G": 1, "B": 2}


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


def _principled(mat: bpy.types.Material) -> bpy.types.Node | None:
    if mat.node_tree is None:
        return None
    return next((n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED"), None)


def _image_pixels(image: bpy.types.Image, max_texture: int, notes: list[str]) -> np.ndarray | None:
    """Linear float RGBA, top row first; None (noted) when the image has no data."""
    w, h = image.size
    if w == 0 or h == 0:
        notes.append(f"missing texture {image.name!r} ({image.filepath or 'no file'}): socket value used")
        return None
    if max(w, h) > max_texture:
        f = max_texture / max(w, h)
        image.scale(max(1, round(w * f)), max(1, round(h * f)))
        notes.append(f"texture {image.name!r} downscaled from {w}x{h} to {image.size[0]}x{image.size[1]}")
        w, h = image.size
    px = np.empty(w * h * image.channels, np.float32)
    image.pixels.foreach_get(px)
    px = np.flipud(px.reshape(h, w, image.channels))
    if image.channels < 3:
        px = np.repeat(px[..., :1], 3, axis=-1)
    if not image.is_float and image.colorspace_settings.name == "sRGB":
        px = np.concatenate([srgb_to_linear(px[..., :3]), px[..., 3:]], axis=-1)
    return px


def _socket_map(socket: bpy.types.NodeSocket, channels: int, max_texture: int,
                notes: list[str]) -> ParamMap:
    default = socket.default_value
    constant = ParamMap(np.array(list(default)[:3] if channels == 3 else [float(default)], np.float32))
    if not socket.is_linked:
        return constant
    link = socket.links[0]
    node, channel = link.from_node, None
    if node.type == "SEPARATE_COLOR" and node.inputs[0].is_linked:
        channel = _CHANNEL.get(link.from_socket.name)
        node = node.inputs[0].links[0].from_node
    if node.type != "TEX_IMAGE" or node.image is None:
        notes.append(f"{socket.name}: input node {node.bl_idname} not followed, socket value used")
        return constant
    px = _image_pixels(node.image, max_texture, notes)
    if px is None:
        return constant
    if channels == 3:
        return ParamMap(np.ascontiguousarray(px[..., :3]))
    return ParamMap(np.ascontiguousarray(px[..., channel if channel is not None else 0:][..., :1]))


def read_pbr(mat: bpy.types.Material, max_texture: int) -> MaterialSource:
    notes: list[str] = []
    node = _principled(mat)
    if node is None:
        notes.append("no Principled BSDF: viewport colour, roughness and metallic used")
        pbr = PbrInputs(mat.name, ParamMap(np.array(mat.diffuse_color[:3], np.float32)),
                        ParamMap.constant(mat.roughness), ParamMap.constant(mat.metallic))
        return MaterialSource(mat, pbr, notes)
    pbr = PbrInputs(mat.name, _socket_map(node.inputs["Base Color"], 3, max_texture, notes),
                    _socket_map(node.inputs["Roughness"], 1, max_texture, notes),
                    _socket_map(node.inputs["Metallic"], 1, max_texture, notes))
    return MaterialSource(mat, pbr, notes)


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
            import xatlas
        except ImportError:
            notes.append(f"{obj.name}: no UVs and xatlas is not installed in this Python: not unwrapped")
            continue
        _xatlas_unwrap(mesh, xatlas)
        notes.append(f"{obj.name}: no UVs, unwrapped with xatlas")
    return notes


def _xatlas_unwrap(mesh: bpy.types.Mesh, xatlas) -> None:  # type: ignore[no-untyped-def]
    bm = bmesh.new()
    bm.from_mesh(mesh)
    bmesh.ops.triangulate(bm, faces=bm.faces[:])
    bm.to_mesh(mesh)
    bm.free()
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    loops = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", loops)
    _, indices, uvs = xatlas.parametrize(co.reshape(-1, 3), loops.reshape(-1, 3).astype(np.uint32))
    layer = mesh.uv_layers.new(name="UVMap")
    layer.data.foreach_set("uv", uvs[indices.reshape(-1)].astype(np.float32).ravel())


def material_surfaces(mat: bpy.types.Material) -> list[tuple[bpy.types.Object, list[int]]]:
    """Every mesh object using ``mat`` and its slots holding it: together they fill its texture space."""
    surfaces = [(o, [i for i, s in enumerate(o.material_slots) if s.material == mat]) for o in mesh_objects()]
    return [(o, slots) for o, slots in surfaces if slots]
