"""World normals and positions of an object's surface in a material's texture space.

Dust settles on upward-facing surfaces, so its weight needs each texel's world
normal (and position, for the triplanar masks). The object's evaluated mesh is
read with ``foreach_get`` (loop triangles of the material's slot, corner normals,
the active render UV map) and rasterised by ``core.uv_raster``.
"""
from __future__ import annotations

import bpy
import numpy as np

from ..core.maps import ParamMap
from ..core.uv_raster import rasterize


def has_uvs(obj: bpy.types.Object) -> bool:
    return obj.type == "MESH" and len(obj.data.uv_layers) > 0


def _render_uv(mesh: bpy.types.Mesh) -> bpy.types.MeshUVLoopLayer:
    return next((uv for uv in mesh.uv_layers if uv.active_render), mesh.uv_layers[0])


def world_maps(obj: bpy.types.Object, slot_index: int, size: tuple[int, int]
               ) -> tuple[ParamMap | None, ParamMap | None, str | None]:
    """(normals, positions, None), or (None, None, reason) when there is no texture space."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        if not mesh.uv_layers:
            return None, None, f"{obj.name!r} has no UV map"
        mesh.calc_loop_triangles()
        n_tris = len(mesh.loop_triangles)
        loops = np.empty(n_tris * 3, np.int32)
        mesh.loop_triangles.foreach_get("loops", loops)
        mat_index = np.empty(n_tris, np.int32)
        mesh.loop_triangles.foreach_get("material_index", mat_index)
        keep = np.repeat(mat_index == slot_index, 3)
        loops = loops[keep]
        if not len(loops):
            return None, None, f"no face of {obj.name!r} uses slot {slot_index}"
        vert_of_loop = np.empty(len(mesh.loops), np.int32)
        mesh.loops.foreach_get("vertex_index", vert_of_loop)
        co = np.empty(len(mesh.vertices) * 3, np.float32)
        mesh.vertices.foreach_get("co", co)
        normals = np.empty(len(mesh.loops) * 3, np.float32)
        mesh.corner_normals.foreach_get("vector", normals)
        uvs = np.empty(len(mesh.loops) * 2, np.float32)
        _render_uv(mesh).uv.foreach_get("vector", uvs)
    finally:
        evaluated.to_mesh_clear()
    matrix = np.array(obj.matrix_world, np.float64)
    pos = co.reshape(-1, 3)[vert_of_loop[loops]] @ matrix[:3, :3].T + matrix[:3, 3]
    normal_matrix = np.linalg.inv(matrix[:3, :3]).T
    nrm = normals.reshape(-1, 3)[loops] @ normal_matrix.T
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
    indices = np.arange(len(loops), dtype=np.int64).reshape(-1, 3)
    raster, reason = rasterize(pos.astype(np.float32), nrm.astype(np.float32),
                               uvs.reshape(-1, 2)[loops], indices, size, flip_v=True)
    if raster is None:
        return None, None, reason
    return ParamMap(raster.normals), ParamMap(raster.positions), None
