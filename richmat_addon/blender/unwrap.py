"""A UV map for meshes that have none, with xatlas (charts packed without overlap).

One unwrapper for the add-on's Unwrap UVs and the farm. xatlas charts
triangles: a face of more than three corners whose triangles land in two charts
shares corners between them, and those corners can hold only one chart's UVs,
so such a face is stretched across the gap. The farm triangulates first
(``triangulate=True``), which makes every face a chart triangle and the atlas
exact; the add-on keeps the user's topology and counts the stretched faces, so
the user is told and can triangulate first.

xatlas is a pip package, not part of Blender: where it is missing (a stock
Blender) the map comes from Blender's own Smart UV Project, which cuts along
faces and so stretches none; the report says which made the map.
"""
from __future__ import annotations

from dataclasses import dataclass

import bmesh
import bpy
import numpy as np

from .pbr_source import InputProblem

UV_NAME = "richmat_uv"
MAX_UV_MAPS = 8  # Blender's limit per mesh


@dataclass(frozen=True)
class Unwrapped:
    faces: int
    stretched: int  # faces whose triangles xatlas put in different charts
    method: str = "xatlas"

    def message(self, name: str) -> str:
        text = f"UV map added to {name} ({self.method})"
        if self.stretched:
            text += (f"; {self.stretched} of {self.faces} faces span two UV charts and are stretched: "
                     "triangulate the mesh (Face > Triangulate Faces) and unwrap again to avoid it")
        return text


def unwrap(obj: bpy.types.Object, triangulate: bool = False) -> Unwrapped:
    """Add (and make active for rendering) a UV map computed by xatlas, else by Smart UV Project."""
    mesh = obj.data
    if triangulate:
        bm = bmesh.new()
        bm.from_mesh(mesh)
        bmesh.ops.triangulate(bm, faces=bm.faces[:])
        bm.to_mesh(mesh)
        bm.free()
    mesh.calc_loop_triangles()
    n_tris = len(mesh.loop_triangles)
    if n_tris == 0:
        raise InputProblem(f"{obj.name!r} has no faces to unwrap")
    if len(mesh.uv_layers) >= MAX_UV_MAPS:
        raise InputProblem(f"{obj.name!r} already has the maximum number of UV maps")
    try:
        import xatlas
    except ImportError:
        return _smart_project(obj)
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    tri_verts = np.empty(n_tris * 3, np.int32)
    mesh.loop_triangles.foreach_get("vertices", tri_verts)
    tri_loops = np.empty(n_tris * 3, np.int32)
    mesh.loop_triangles.foreach_get("loops", tri_loops)
    _, indices, uvs = xatlas.parametrize(co.reshape(-1, 3), tri_verts.reshape(-1, 3).astype(np.uint32))
    loop_uv = np.zeros((len(mesh.loops), 2), np.float32)
    corner_uv = uvs[indices.reshape(-1)]
    loop_uv[tri_loops] = corner_uv
    # A loop shared by two triangles keeps the last one's UV; where the other disagrees, the face spans two charts.
    disagree = np.abs(loop_uv[tri_loops] - corner_uv).max(-1).reshape(-1, 3).max(-1) > 1e-6
    tri_faces = np.empty(n_tris, np.int32)
    mesh.loop_triangles.foreach_get("polygon_index", tri_faces)
    layer = _new_layer(mesh)
    layer.uv.foreach_set("vector", loop_uv.ravel())
    return Unwrapped(len(mesh.polygons), len(np.unique(tri_faces[disagree])))


def _new_layer(mesh: bpy.types.Mesh) -> bpy.types.MeshUVLoopLayer:
    """A new UV map, active in the viewport and for rendering."""
    layer = mesh.uv_layers.new(name=UV_NAME)
    mesh.uv_layers.active = layer
    layer.active_render = True
    return layer


def _smart_project(obj: bpy.types.Object) -> Unwrapped:
    """Blender's Smart UV Project on every face; the mesh's selection, hidden faces and mode are kept."""
    mesh = obj.data
    kept = {(items, attr): _flags(getattr(mesh, items), attr) for items in ("vertices", "edges", "polygons")
            for attr in ("select", "hide")}
    mode = obj.mode
    _new_layer(mesh)
    layer_objects = bpy.context.view_layer.objects
    was_active = layer_objects.active
    layer_objects.active = obj  # edit mode enters the view layer's active object, whatever the override says
    try:
        _smart_project_active(obj, mesh, kept, mode)
    finally:
        layer_objects.active = was_active
    return Unwrapped(len(mesh.polygons), 0, "Smart UV Project: xatlas is not installed in Blender's Python")


def _smart_project_active(obj: bpy.types.Object, mesh: bpy.types.Mesh, kept: dict, mode: str) -> None:
    with bpy.context.temp_override(active_object=obj, object=obj, edit_object=obj, selected_objects=[obj],
                                   selected_editable_objects=[obj]):
        bpy.ops.object.mode_set(mode="EDIT")
        bpy.ops.mesh.reveal(select=False)
        bpy.ops.mesh.select_all(action="SELECT")
        bpy.ops.uv.smart_project()
        bpy.ops.object.mode_set(mode="OBJECT")
        for (items, attr), flags in kept.items():
            getattr(mesh, items).foreach_set(attr, flags)
        mesh.update()
        if mode != "OBJECT":
            bpy.ops.object.mode_set(mode=mode)


def _flags(items: bpy.types.bpy_prop_collection, attr: str) -> np.ndarray:
    out = np.empty(len(items), bool)
    items.foreach_get(attr, out)
    return out
