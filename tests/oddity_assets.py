"""Tiny glTF assets with the oddities Objaverse is full of, for tests/test_batch_oddities.py.

Each writer puts one asset (and its side files) into a folder and returns its path.
All are written by hand with numpy and struct, except the Draco mesh: only Blender's
exporter encodes Draco here. docs/batch.md's table of oddities names each one.
"""
from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from support.blender_child import run_blender
from tests.test_gltf_io import _Builder, base_color_image, cube_arrays, orm_image, png
from torch_models.assets.gltf_container import glb_bytes

# The 12-byte KTX2 identifier and a little body: enough for anything that sniffs the format.
KTX2_BYTES = b"\xabKTX 20\xbb\r\n\x1a\n" + bytes(68)
SKIN_LIFT = 3.0  # how far the skinned asset's animation moves its root at frame 1


def _document(b: _Builder, meshes: list[dict[str, Any]], nodes: list[dict[str, Any]],
              materials: list[dict[str, Any]], **extra: Any) -> dict[str, Any]:
    """A glTF document over the builder's buffer: one scene holding the root nodes."""
    children = {c for n in nodes for c in n.get("children", [])}
    return {"asset": {"version": "2.0"}, "scene": 0,
            "scenes": [{"nodes": [i for i in range(len(nodes)) if i not in children]}],
            "nodes": nodes, "meshes": meshes, "materials": materials, **extra,
            "buffers": [{"byteLength": len(b.bin)}], "bufferViews": b.views, "accessors": b.accessors}


def _cube_primitive(b: _Builder, material: int | None = 0, uv: bool = True) -> dict[str, Any]:
    pos, nrm, uvs, idx = cube_arrays()
    attributes = {"POSITION": b.accessor(pos), "NORMAL": b.accessor(nrm)}
    if uv:
        attributes["TEXCOORD_0"] = b.accessor(uvs)
    prim: dict[str, Any] = {"attributes": attributes, "indices": b.accessor(idx.reshape(-1))}
    if material is not None:
        prim["material"] = material
    return prim


def _write_glb(path: Path, doc: dict[str, Any], b: _Builder) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(glb_bytes(doc, bytes(b.bin)))
    return path


def write_draco(folder: Path) -> Path:
    """A sphere (one plain material) exported by Blender with KHR_draco_mesh_compression."""
    path = folder / "draco.glb"
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as scratch:  # Blender's script and user folder stay out of the assets
        run_blender(f"""
import bpy
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=8)
mat = bpy.data.materials.new("clay")
mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.8, 0.3, 0.1, 1.0)
bpy.context.active_object.data.materials.append(mat)
bpy.ops.export_scene.gltf(filepath={str(path)!r}, export_format="GLB", export_draco_mesh_compression_enable=True)
""", Path(scratch))
    return path


def write_ktx2(folder: Path, fallback: bool) -> Path:
    """A cube whose base colour texture is KTX2/Basis (KHR_texture_basisu).

    With ``fallback`` the texture also names a PNG ``source`` (the extension is only
    used); without, the KTX2 image is all there is and the extension is required.
    """
    b = _Builder()
    images = [{"bufferView": b.view(KTX2_BYTES), "mimeType": "image/ktx2", "name": "basis"}]
    texture: dict[str, Any] = {"extensions": {"KHR_texture_basisu": {"source": 0}}}
    if fallback:
        images.append({"bufferView": b.view(png(base_color_image())), "mimeType": "image/png", "name": "png"})
        texture["source"] = 1
    material = {"name": "basis", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                          "baseColorFactor": [0.2, 0.6, 0.9, 1.0]}}
    doc = _document(b, [{"primitives": [_cube_primitive(b)]}], [{"mesh": 0}], [material],
                    textures=[texture], images=images, extensionsUsed=["KHR_texture_basisu"])
    if not fallback:
        doc["extensionsRequired"] = ["KHR_texture_basisu"]
    return _write_glb(folder / ("ktx2_fallback.glb" if fallback else "ktx2_only.glb"), doc, b)


def write_vertex_colours(folder: Path) -> Path:
    """A cube coloured by COLOR_0 alone: no texture, no UVs, the default material."""
    b = _Builder()
    prim = _cube_primitive(b, material=None, uv=False)
    pos = cube_arrays()[0]
    colours = np.concatenate([pos + 0.5, np.ones((len(pos), 1))], axis=1).astype(np.float32)
    prim["attributes"]["COLOR_0"] = b.accessor(colours)
    return _write_glb(folder / "vertex_colours.glb", _document(b, [{"primitives": [prim]}], [{"mesh": 0}], []), b)


def write_uv_sets(folder: Path) -> Path:
    """A cube with TEXCOORD_0 and TEXCOORD_1 whose maps all read the second set."""
    b = _Builder()
    prim = _cube_primitive(b)
    prim["attributes"]["TEXCOORD_1"] = b.accessor(cube_arrays()[2][:, ::-1].copy())
    images = [{"bufferView": b.view(png(base_color_image())), "mimeType": "image/png"},
              {"bufferView": b.view(png(orm_image())), "mimeType": "image/png"}]
    material = {"name": "second_uv", "pbrMetallicRoughness": {
        "baseColorTexture": {"index": 0, "texCoord": 1}, "metallicRoughnessTexture": {"index": 1, "texCoord": 1}}}
    doc = _document(b, [{"primitives": [prim]}], [{"mesh": 0}], [material],
                    textures=[{"source": 0}, {"source": 1}], images=images)
    return _write_glb(folder / "uv_sets.glb", doc, b)


def write_alpha_blend(folder: Path) -> Path:
    """Two cubes: a pane with alpha blending (alphaMode BLEND, base colour alpha 0.4), an opaque frame."""
    b = _Builder()
    materials = [{"name": "pane", "alphaMode": "BLEND",
                  "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.5, 0.9, 0.4]}},
                 {"name": "frame", "pbrMetallicRoughness": {"baseColorFactor": [0.3, 0.3, 0.3, 1.0]}}]
    meshes = [{"primitives": [_cube_primitive(b, material=0)]}, {"primitives": [_cube_primitive(b, material=1)]}]
    nodes = [{"mesh": 0}, {"mesh": 1, "translation": [2, 0, 0]}]
    return _write_glb(folder / "alpha_blend.glb", _document(b, meshes, nodes, materials), b)


def _column() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 0.8-wide column from y = 0 to 2 in two segments: positions, joint of each vertex, triangles."""
    ring = np.float32([[-0.4, 0, -0.4], [0.4, 0, -0.4], [0.4, 0, 0.4], [-0.4, 0, 0.4]])
    pos = np.concatenate([ring + np.float32([0, y, 0]) for y in (0, 1, 2)])
    joints = np.repeat([0, 0, 1], 4)
    tris = []
    for level in (0, 4):
        for i in range(4):
            a, c = level + i, level + (i + 1) % 4
            tris += [(a, c, c + 4), (a, c + 4, a + 4)]
    tris += [(0, 2, 1), (0, 3, 2), (8, 9, 10), (8, 10, 11)]
    return pos, joints, np.uint16(tris)


def _quat_z(degrees: float) -> list[float]:
    half = math.radians(degrees) / 2
    return [0.0, 0.0, math.sin(half), math.cos(half)]


def write_skinned(folder: Path) -> Path:
    """A column skinned to two joints whose file pose bends it, animated to bend and lift.

    Rest pose: straight, standing on the origin. The nodes' own pose bends the
    upper joint 90 degrees; the animation lifts the root by ``SKIN_LIFT`` at frame 1
    (t = 1/24 s) and bends the upper joint further.
    """
    b = _Builder()
    pos, joints, tris = _column()
    joint_index = np.zeros((len(pos), 4), np.uint8)
    joint_index[:, 0] = joints
    weights = np.zeros((len(pos), 4), np.float32)
    weights[:, 0] = 1.0
    prim = {"attributes": {"POSITION": b.accessor(pos), "JOINTS_0": b.accessor(joint_index),
                           "WEIGHTS_0": b.accessor(weights)}, "indices": b.accessor(tris.reshape(-1)),
            "material": 0}
    inverse_bind = np.stack([np.eye(4), np.eye(4)]).astype(np.float32)
    inverse_bind[1, 1, 3] = -1.0  # the upper joint sits at y = 1
    inverse_bind = inverse_bind.transpose(0, 2, 1).reshape(2, 16).copy()  # glTF matrices are column-major
    times = b.accessor(np.float32([0.0, 1.0 / 24.0]))
    lift = b.accessor(np.float32([[0, 0, 0], [0, SKIN_LIFT, 0]]))
    bend = b.accessor(np.float32([_quat_z(90), _quat_z(150)]))
    nodes = [{"name": "body", "mesh": 0, "skin": 0},
             {"name": "root", "children": [2]},
             {"name": "upper", "translation": [0, 1, 0], "rotation": _quat_z(90)}]
    animation = {"name": "wave", "samplers": [{"input": times, "output": lift}, {"input": times, "output": bend}],
                 "channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}},
                              {"sampler": 1, "target": {"node": 2, "path": "rotation"}}]}
    doc = _document(b, [{"primitives": [prim]}], nodes, [{"name": "skin_paint", "pbrMetallicRoughness": {
        "baseColorFactor": [0.3, 0.7, 0.3, 1.0]}}],
        skins=[{"joints": [1, 2], "inverseBindMatrices": b.accessor(inverse_bind), "skeleton": 1}],
        animations=[animation])
    return _write_glb(folder / "skinned.glb", doc, b)


def write_lights_cameras(folder: Path) -> Path:
    """A cube under a camera node (moved by it), two KHR_lights_punctual lights and a second camera."""
    b = _Builder()
    nodes = [{"name": "eye", "camera": 0, "translation": [5, 0, 0], "children": [1]},
             {"name": "box", "mesh": 0},
             {"name": "sun", "extensions": {"KHR_lights_punctual": {"light": 0}}},
             {"name": "lamp", "translation": [0, 2, 0], "extensions": {"KHR_lights_punctual": {"light": 1}}},
             {"name": "eye2", "camera": 1, "translation": [0, 0, 4]}]
    camera = {"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}
    lights = [{"type": "directional", "intensity": 3.0}, {"type": "point", "intensity": 50.0}]
    doc = _document(b, [{"primitives": [_cube_primitive(b)]}], nodes,
                    [{"name": "lit", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.9, 0.2, 1.0]}}],
                    cameras=[camera, dict(camera)], extensionsUsed=["KHR_lights_punctual"],
                    extensions={"KHR_lights_punctual": {"lights": lights}})
    return _write_glb(folder / "lights_cameras.glb", doc, b)


def _grid(cells: int) -> tuple[np.ndarray, np.ndarray]:
    """A flat square of cells x cells quads: vertex positions (y = 0) and quads (4 vertex indices each)."""
    ticks = np.linspace(-1, 1, cells + 1, dtype=np.float32)
    x, z = np.meshgrid(ticks, ticks)
    pos = np.stack([x.ravel(), np.zeros(x.size, np.float32), z.ravel()], axis=1)
    corner = (np.arange(cells)[:, None] * (cells + 1) + np.arange(cells)[None, :]).ravel()
    return pos, np.stack([corner, corner + cells + 1, corner + cells + 2, corner + 1], axis=1)


def write_huge(folder: Path, cells: int) -> Path:
    """A glTF grid of 2 * cells^2 triangles: a polycount that stands in for a huge one."""
    b = _Builder()
    pos, quads = _grid(cells)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]).astype(np.uint32)
    prim = {"attributes": {"POSITION": b.accessor(pos)}, "indices": b.accessor(tris.reshape(-1))}
    return _write_glb(folder / "huge.glb", _document(b, [{"primitives": [prim]}], [{"mesh": 0}], []), b)


def write_huge_obj(folder: Path, cells: int) -> Path:
    """The same grid as an OBJ of quads (2 * cells^2 triangles): counted after the import."""
    pos, quads = _grid(cells)
    lines = [f"v {x:g} {y:g} {z:g}" for x, y, z in pos] + [f"f {a} {b} {c} {d}" for a, b, c, d in quads + 1]
    path = folder / "huge_quads.obj"
    path.write_text("\n".join(lines) + "\n")
    return path


def _textured_gltf(path: Path, buffer_uri: str, image_uri: str) -> Path:
    """A .gltf cube whose buffer and base colour image are external files with the given URIs."""
    b = _Builder()
    doc = _document(b, [{"primitives": [_cube_primitive(b)]}], [{"mesh": 0}],
                    [{"name": "painted", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                                  "baseColorFactor": [0.5, 0.5, 0.5, 1.0]}}],
                    textures=[{"source": 0}], images=[{"uri": image_uri, "name": "paint"}])
    doc["buffers"][0]["uri"] = buffer_uri
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc))
    (path.parent / "cube.bin").write_bytes(bytes(b.bin))
    return path


def write_missing_buffer(folder: Path) -> Path:
    """A .gltf whose buffer file is missing (its texture is there)."""
    gltf = _textured_gltf(folder / "missing_buffer" / "missing_buffer.gltf", "gone.bin", "paint.png")
    (gltf.parent / "paint.png").write_bytes(png(base_color_image()))
    return gltf


def write_missing_image(folder: Path) -> Path:
    """A .gltf whose texture image file is missing (its buffer is there)."""
    return _textured_gltf(folder / "missing_image" / "missing_image.gltf", "cube.bin", "gone.png")


def write_outside_uris(folder: Path) -> tuple[Path, Path]:
    """A .gltf whose image URI leads out of its folder, to a fifo any reader would hang on.

    Returns the .gltf and the fifo: opening the fifo for reading blocks until a writer
    comes, so an importer that read it would never finish.
    """
    gltf = _textured_gltf(folder / "escape" / "escape.gltf", "cube.bin", "../outside/paint.png")
    fifo = folder / "outside" / "paint.png"
    fifo.parent.mkdir(parents=True, exist_ok=True)
    os.mkfifo(fifo)
    return gltf, fifo
