"""Blender side, scene: import any supported file safely, check it, normalise it to the unit cube.

Imports use Blender 5.0's operators (the 4.x ``import_scene.obj`` family is
gone). A ``.blend`` is appended with ``libraries.load``, never opened as the
main file, with auto-execution off: its drivers and registered text blocks do
not run (``bpy.app.autoexec_fail`` says whether something tried), and its
drivers are removed before the scene is saved for the render stage. A glTF goes
through ``gltf_import`` first (URIs checked, triangles counted, what Blender
cannot read taken out). The dataset renders every asset in its rest pose, with
its own camera and light probe: animation is removed, armatures are set to their
rest position and the asset's lights and cameras are dropped, each with a note.
"""
from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any, Callable

import bpy
import numpy as np
from mathutils import Matrix, Vector

from torch_models.assets.gltf_container import GltfError

from . import gltf_import


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


def _import_gltf(path: Path) -> None:
    # no bone display shapes: the importer would add them to the scene as mesh objects
    bpy.ops.import_scene.gltf(filepath=str(path), disable_bone_shape=True)


IMPORTERS: dict[str, Callable[[Path], Any]] = {
    ".glb": _import_gltf,
    ".gltf": _import_gltf,
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


def refuse_over(triangles: int, limit: int) -> None:
    if triangles > limit:
        raise BadAsset(f"the meshes have {triangles} triangles, more than --max-triangles {limit}: refused")


def import_asset(path: Path, max_triangles: int) -> tuple[dict[str, Any], list[str]]:
    """Import into the empty scene: what it did (auto-execution) and its notes.

    Raises BadAsset with the importer's message on failure; a glTF over
    ``max_triangles`` is refused before the import, from its JSON.
    """
    importer = IMPORTERS.get(path.suffix.lower())
    if importer is None:
        raise BadAsset(f"unsupported format {path.suffix!r}")
    notes: list[str] = []
    try:
        with tempfile.TemporaryDirectory(prefix="richmat-import-") as scratch:
            if path.suffix.lower() in (".gltf", ".glb"):
                prepared = gltf_import.prepare(path, Path(scratch))
                refuse_over(prepared.triangles, max_triangles)
                path, notes = prepared.path, prepared.notes
            importer(path)
    except GltfError as exc:
        raise BadAsset(f"import failed: {exc.problem}") from None
    except (RuntimeError, OSError, ValueError, KeyError, IndexError, TypeError, AttributeError) as exc:
        message = str(exc).strip().splitlines()
        raise BadAsset(f"import failed: {message[-1] if message else type(exc).__name__}") from None
    return {"autoexec_fail": bool(bpy.app.autoexec_fail),
            "autoexec_fail_message": bpy.app.autoexec_fail_message or None}, notes


def _animatable() -> list[bpy.types.ID]:
    """The data-blocks an imported asset can animate (materials' node trees included)."""
    kinds = (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.shape_keys, bpy.data.armatures,
             bpy.data.node_groups, bpy.data.curves, bpy.data.scenes, bpy.data.worlds)
    return [b for kind in kinds for b in kind] + [m.node_tree for m in bpy.data.materials if m.node_tree]


def _remove_keeping_children(obj: bpy.types.Object) -> None:
    """Remove ``obj``; its children keep their place in the world (a camera node may carry the mesh)."""
    for child in obj.children:
        world = child.matrix_world.copy()
        child.parent = None
        child.matrix_world = world
    bpy.data.objects.remove(obj)


def remove_drivers_and_extras() -> tuple[dict[str, int], list[str]]:
    """Drop what the dataset does not want from an asset; the counts, and a note for each kind.

    Drivers, animation, lights, cameras, text blocks, freestyle go; armatures are set
    to their rest position, so every frame shows the same rest pose.
    """
    counts = {"drivers": 0, "animated": 0, "lights": 0, "cameras": 0, "texts": len(bpy.data.texts)}
    bpy.context.view_layer.update()  # parents' world matrices, before any is removed
    for block in _animatable():
        anim = block.animation_data
        if anim is not None:
            counts["drivers"] += len(anim.drivers)
            counts["animated"] += int(anim.action is not None or len(anim.nla_tracks) > 0)
            block.animation_data_clear()
    for obj in list(bpy.data.objects):
        if obj.type in ("LIGHT", "CAMERA"):
            counts["lights" if obj.type == "LIGHT" else "cameras"] += 1
            _remove_keeping_children(obj)
    for text in list(bpy.data.texts):
        bpy.data.texts.remove(text)
    bpy.context.scene.render.use_freestyle = False
    skinned = [o.name for o in mesh_objects() if any(m.type == "ARMATURE" and m.object for m in o.modifiers)]
    for armature in bpy.data.armatures:
        armature.pose_position = "REST"
    notes = []
    if counts["lights"] or counts["cameras"]:
        notes.append(f"{counts['lights']} light(s) and {counts['cameras']} camera(s) in the asset ignored: "
                     "the dataset's camera orbit and light probe are used")
    if counts["animated"]:
        notes.append(f"animation of {counts['animated']} data-block(s) removed: rendered in the rest pose")
    if skinned:
        notes.append(f"skinned mesh(es) {', '.join(map(repr, sorted(skinned)))}: rendered in the rest pose")
    return counts, notes


def mesh_objects() -> list[bpy.types.Object]:
    return [o for o in bpy.context.scene.objects if o.type == "MESH"]


def check_geometry(max_triangles: int) -> dict[str, int]:
    meshes = mesh_objects()
    if not meshes:
        raise BadAsset("no mesh objects after import (empty, truncated or unreadable file)")
    faces = sum(len(o.data.polygons) for o in meshes)
    if faces == 0:
        raise BadAsset(f"zero faces in {len(meshes)} mesh object(s): nothing to render")
    triangles = sum(len(o.data.loops) - 2 * len(o.data.polygons) for o in meshes)  # a k-gon is k - 2 triangles
    refuse_over(triangles, max_triangles)
    return {"mesh_objects": len(meshes), "faces": faces, "triangles": triangles,
            "vertices": sum(len(o.data.vertices) for o in meshes)}


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
