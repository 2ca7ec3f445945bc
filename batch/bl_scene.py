"""Blender side, scene: import any supported file safely, check it, normalise it to the unit cube.

Imports use Blender 5.0's operators (the 4.x ``import_scene.obj`` family is
gone). A ``.blend`` is appended with ``libraries.load``, never opened as the
main file, with auto-execution off: its drivers and registered text blocks do
not run (``bpy.app.autoexec_fail`` says whether something tried), and its
drivers are removed before the scene is saved for the render stage.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import bpy
import numpy as np
from mathutils import Matrix, Vector

from richmat_addon.core.gltf_materials import GltfError, external_files


class BadAsset(Exception):
    """The asset cannot be rendered; the message is the ledger's reason."""


def _import_blend(path: Path) -> None:
    bpy.context.preferences.filepaths.use_scripts_auto_execute = False
    with bpy.data.libraries.load(str(path), link=False) as (source, target):
        target.objects = list(source.objects)
    for obj in target.objects:
        if obj is not None:
            bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.update()  # evaluates drivers (blocked): autoexec_fail then says whether any tried


IMPORTERS: dict[str, Callable[[Path], Any]] = {
    ".glb": lambda p: bpy.ops.import_scene.gltf(filepath=str(p)),
    ".gltf": lambda p: bpy.ops.import_scene.gltf(filepath=str(p)),
    ".obj": lambda p: bpy.ops.wm.obj_import(filepath=str(p)),
    ".fbx": lambda p: bpy.ops.import_scene.fbx(filepath=str(p)),
    ".ply": lambda p: bpy.ops.wm.ply_import(filepath=str(p)),
    ".stl": lambda p: bpy.ops.wm.stl_import(filepath=str(p)),
    **{ext: (lambda p: bpy.ops.wm.usd_import(filepath=str(p))) for ext in (".usd", ".usda", ".usdc", ".usdz")},
    ".blend": _import_blend,
}


def empty_scene() -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.preferences.filepaths.use_scripts_auto_execute = False


def import_asset(path: Path) -> dict[str, Any]:
    """Import into the empty scene; raise BadAsset with the importer's message on failure."""
    importer = IMPORTERS.get(path.suffix.lower())
    if importer is None:
        raise BadAsset(f"unsupported format {path.suffix!r}")
    try:
        if path.suffix.lower() in (".gltf", ".glb"):  # Blender's importer reads URIs unchecked
            external_files(path)
        importer(path)
    except GltfError as exc:
        raise BadAsset(f"import failed: {exc.problem}") from None
    except (RuntimeError, OSError, ValueError, KeyError, IndexError, TypeError, AttributeError) as exc:
        message = str(exc).strip().splitlines()
        raise BadAsset(f"import failed: {message[-1] if message else type(exc).__name__}") from None
    return {"autoexec_fail": bool(bpy.app.autoexec_fail),
            "autoexec_fail_message": bpy.app.autoexec_fail_message or None}


def remove_drivers_and_extras() -> dict[str, int]:
    """Drop what the dataset does not want from an asset: drivers, lights, cameras, freestyle, texts."""
    counts = {"drivers": 0, "lights": 0, "cameras": 0, "texts": len(bpy.data.texts)}
    for collection in (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.shape_keys):
        for block in collection:
            anim = block.animation_data
            if anim is not None:
                counts["drivers"] += len(anim.drivers)
                block.animation_data_clear()
    for obj in list(bpy.data.objects):
        if obj.type in ("LIGHT", "CAMERA"):
            counts["lights" if obj.type == "LIGHT" else "cameras"] += 1
            bpy.data.objects.remove(obj)
    for text in list(bpy.data.texts):
        bpy.data.texts.remove(text)
    bpy.context.scene.render.use_freestyle = False
    return counts


def mesh_objects() -> list[bpy.types.Object]:
    return [o for o in bpy.context.scene.objects if o.type == "MESH"]


def check_geometry() -> dict[str, int]:
    meshes = mesh_objects()
    if not meshes:
        raise BadAsset("no mesh objects after import (empty, truncated or unreadable file)")
    faces = sum(len(o.data.polygons) for o in meshes)
    if faces == 0:
        raise BadAsset(f"zero faces in {len(meshes)} mesh object(s): nothing to render")
    return {"mesh_objects": len(meshes), "faces": faces, "vertices": sum(len(o.data.vertices) for o in meshes)}


def world_vertices(obj: bpy.types.Object) -> np.ndarray:
    co = np.empty(len(obj.data.vertices) * 3, np.float32)
    obj.data.vertices.foreach_get("co", co)
    m = np.array(obj.matrix_world, np.float64)
    co = co.reshape(-1, 3).astype(np.float64)
    return co @ m[:3, :3].T + m[:3, 3]


def normalise() -> dict[str, Any]:
    """Fit all meshes into the cube [-0.5, 0.5]^3 under one new root (several roots stay together)."""
    view_layer = bpy.context.view_layer
    view_layer.update()
    points = np.concatenate([world_vertices(o) for o in mesh_objects() if len(o.data.vertices)])
    points = points[np.isfinite(points).all(1)]
    lo, hi = points.min(0), points.max(0)
    extent = float((hi - lo).max())
    if not extent > 0:
        raise BadAsset("degenerate bounding box (all vertices at one point)")
    scale, centre = 1.0 / extent, (lo + hi) / 2
    root = bpy.data.objects.new("richmat_root", None)
    bpy.context.scene.collection.objects.link(root)
    for obj in [o for o in bpy.context.scene.objects if o.parent is None and o is not root]:
        world = obj.matrix_world.copy()
        obj.parent = root
        obj.matrix_world = world
    root.matrix_world = Matrix.Diagonal((scale, scale, scale, 1.0)) @ Matrix.Translation(-Vector(centre))
    view_layer.update()
    return {"scale": scale, "offset": [float(-c) for c in centre], "bbox_min": lo.tolist(), "bbox_max": hi.tolist()}
