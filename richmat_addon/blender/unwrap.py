"""A UV map for meshes that have none, with xatlas (charts packed without overlap).

One unwrapper for the add-on's Unwrap UVs and the farm. xatlas charts
triangles: a face of more than three corners whose triangles land in two charts
shares corners between them, and those corners can hold only one chart's UVs,
so such a face is stretched across the gap. The farm triangulates first
(``triangulate=True``), which makes every face a chart triangle and the atlas
exact; the add-on keeps the user's topology and counts the stretched faces, so
the user is told and can triangulate first.

xatlas is a pip package, not part of Blender: where it is missing the user is
told to install it or to use Blender's own Smart UV Project.
"""
from __future__ import annotations

from dataclasses import dataclass

import bmesh
import bpy
import numpy as np

from .pbr_source import InputProblem

UV_NAME = "richmat_uv"


@dataclass(frozen=True)
class Unwrapped:
    faces: int
    stretched: int  # faces whose triangles xatlas put in different charts

    def message(self, name: str) -> str:
        text = f"UV map added to {name} (xatlas)"
        if self.stretched:
            text += (f"; {self.stretched} of {self.faces} faces span two UV charts and are stretched: "
                     "triangulate the mesh (Face > Triangulate Faces) and unwrap again to avoid it")
        return text


def unwrap(obj: bpy.types.Object, triangulate: bool = False) -> Unwrapped:
    """Add (and make active for rendering) a UV map computed by xatlas."""
    try:
        import xatlas
    except ImportError:
        raise InputProblem("xatlas is not installed in Blender's Python: run `<blender python> -m pip install "
                           "xatlas`, or unwrap with UV > Smart UV Project") from None
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
    layer = mesh.uv_layers.new(name=UV_NAME)
    if layer is None:
        raise InputProblem(f"{obj.name!r} already has the maximum number of UV maps")
    layer.uv.foreach_set("vector", loop_uv.ravel())
    mesh.uv_layers.active = layer
    layer.active_render = True
    return Unwrapped(len(mesh.polygons), len(np.unique(tri_faces[disagree])))
