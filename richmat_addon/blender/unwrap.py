"""A UV map for meshes that have none, with xatlas (charts packed without overlap).

One unwrapper for the add-on's Unwrap UVs and the farm. xatlas charts
triangles: a face of more than three corners whose triangles land in two charts
shares corners between them, and those corners can hold only one chart's UVs,
so such a face is stretched across the gap. The farm triangulates first
(``triangulate=True``), which makes every face a chart triangle and the atlas
exact; the add-on keeps the user's topology.

xatlas is a pip package, not part of Blender: where it is missing the user is
told to install it or to use Blender's own Smart UV Project.
"""
from __future__ import annotations

import bmesh
import bpy
import numpy as np

from .pbr_source import InputProblem

UV_NAME = "richmat_uv"


def unwrap(obj: bpy.types.Object, triangulate: bool = False) -> str:
    """Add (and make active for rendering) a UV map computed by xatlas; returns the method used."""
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
    loop_uv[tri_loops] = uvs[indices.reshape(-1)]
    layer = mesh.uv_layers.new(name=UV_NAME)
    if layer is None:
        raise InputProblem(f"{obj.name!r} already has the maximum number of UV maps")
    layer.uv.foreach_set("vector", loop_uv.ravel())
    mesh.uv_layers.active = layer
    layer.active_render = True
    return "xatlas"
