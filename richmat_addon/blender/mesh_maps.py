"""World normals and positions, or a colour attribute, of a material's surfaces in its texture space.

Dust settles on upward-facing surfaces, so its weight needs each texel's world
normal (and position, for the triplanar masks). The object's evaluated mesh is
read with ``foreach_get`` (loop triangles of the material's slots, corner normals,
the active render UV map) and rasterised by ``core.uv_raster``. Used by the
add-on's Uplift/Bake and by ``batch/``, which also bakes vertex colours this way
(the enhancement needs a base colour per texel, not per vertex).
"""
from __future__ import annotations

from collections.abc import Collection, Iterable
from pathlib import Path

import bpy
import numpy as np

from ..core.maps import ParamMap
from ..core.uv_raster import UvRaster, rasterize
from .pbr_source import InputProblem


def has_uvs(obj: bpy.types.Object) -> bool:
    return obj.type == "MESH" and len(obj.data.uv_layers) > 0


def _render_uv(mesh: bpy.types.Mesh) -> bpy.types.MeshUVLoopLayer:
    return next((uv for uv in mesh.uv_layers if uv.active_render), mesh.uv_layers[0])


def _triangles(obj: bpy.types.Object, slots: Collection[int], attribute: str | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None] | None:
    """World positions, unit world normals, UVs and ``attribute``'s linear RGB of the triangle corners in ``slots``.

    None when the object has no UV map or no face in those slots; the colours are
    None without an ``attribute`` ("" names the render colour attribute). The
    evaluated mesh is read (what Cycles renders, modifiers applied) with its render UV map.
    """
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    try:
        if not mesh.uv_layers:
            return None
        mesh.calc_loop_triangles()
        n_tris = len(mesh.loop_triangles)
        loops = np.empty(n_tris * 3, np.int32)
        mesh.loop_triangles.foreach_get("loops", loops)
        mat_index = np.empty(n_tris, np.int32)
        mesh.loop_triangles.foreach_get("material_index", mat_index)
        loops = loops[np.repeat(np.isin(mat_index, list(slots)), 3)]
        if not len(loops):
            return None
        vert_of_loop = np.empty(len(mesh.loops), np.int32)
        mesh.loops.foreach_get("vertex_index", vert_of_loop)
        co = np.empty(len(mesh.vertices) * 3, np.float32)
        mesh.vertices.foreach_get("co", co)
        normals = np.empty(len(mesh.loops) * 3, np.float32)
        mesh.corner_normals.foreach_get("vector", normals)
        uvs = np.empty(len(mesh.loops) * 2, np.float32)
        _render_uv(mesh).uv.foreach_get("vector", uvs)
        colours = None if attribute is None else _corner_colours(mesh, attribute, vert_of_loop)[loops]
    finally:
        evaluated.to_mesh_clear()
    matrix = np.array(obj.matrix_world, np.float64)
    pos = co.reshape(-1, 3)[vert_of_loop[loops]] @ matrix[:3, :3].T + matrix[:3, 3]
    nrm = normals.reshape(-1, 3)[loops] @ np.linalg.inv(matrix[:3, :3])  # inverse transpose, row vectors
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
    return pos, nrm, uvs.reshape(-1, 2)[loops], colours


def _corner_colours(mesh: bpy.types.Mesh, name: str, vert_of_loop: np.ndarray) -> np.ndarray:
    """Linear RGB of a colour attribute per face corner (white when the mesh lacks it)."""
    attrs = mesh.color_attributes
    layer = attrs.get(name) if name else (attrs[attrs.render_color_index] if len(attrs) else None)
    if layer is None:
        return np.ones((len(vert_of_loop), 3), np.float32)
    values = np.empty(len(layer.data) * 4, np.float32)
    layer.data.foreach_get("color", values)  # scene linear, for byte and float attributes alike
    rgb = values.reshape(-1, 4)[:, :3]
    return rgb if layer.domain == "CORNER" else rgb[vert_of_loop]


def _raster(surfaces: Iterable[tuple[bpy.types.Object, Collection[int]]], size: tuple[int, int],
            attribute: str | None = None) -> tuple[UvRaster | None, str | None]:
    """``uv_raster.rasterize`` over every (object, slots); with ``attribute``, its colours take the positions' place."""
    parts = [t for t in (_triangles(obj, slots, attribute) for obj, slots in surfaces) if t is not None]
    if not parts:
        return None, "no face with a UV map uses this material"
    pos, nrm, uv = (np.concatenate(column) for column in list(zip(*parts))[:3])
    if attribute is not None:  # interpolated across each triangle just as positions are
        pos = np.concatenate([p[3] for p in parts])
    indices = np.arange(len(pos), dtype=np.int64).reshape(-1, 3)
    return rasterize(pos.astype(np.float32), nrm.astype(np.float32), uv, indices, size, flip_v=True)


def world_maps(surfaces: Iterable[tuple[bpy.types.Object, Collection[int]]], size: tuple[int, int]
               ) -> tuple[ParamMap | None, ParamMap | None, str | None]:
    """(normals, positions, None) of the faces in the given (object, material slots), or (None, None, reason).

    The add-on passes the one slot it enhances; the batch passes every object
    using a material, since they all share its texture space.
    """
    raster, reason = _raster(surfaces, size)
    if raster is None:
        return None, None, reason
    return ParamMap(raster.normals), ParamMap(raster.positions), None


def coverage(surfaces: Iterable[tuple[bpy.types.Object, Collection[int]]], size: tuple[int, int]
             ) -> np.ndarray | None:
    """The (H, W) texels (top row first) whose centres the faces of the given (object, material slots)
    cover; None where they have no UV map."""
    raster, _ = _raster(surfaces, size)
    return None if raster is None else raster.coverage


def colour_map(surfaces: Iterable[tuple[bpy.types.Object, Collection[int]]], size: tuple[int, int],
               attribute: str) -> tuple[np.ndarray | None, str | None]:
    """(the colour attribute as an (H, W, 3) linear RGB map, None), or (None, reason).

    Texels no face reaches (beyond the raster's padding) take the mean covered
    colour, so the map's mean is the surface's.
    """
    raster, reason = _raster(surfaces, size, attribute)
    if raster is None:
        return None, reason
    mean = raster.positions[raster.coverage].mean(axis=0)
    return np.where(raster.filled[..., None], raster.positions, mean).astype(np.float32), None


def write_obj(obj: bpy.types.Object, slots: Collection[int], path: Path) -> None:
    """The faces of ``slots`` as a Wavefront OBJ triangle soup for the backend's ``generate``.

    World positions turned Y up (what OBJ readers, and so the backend, expect;
    Blender's own OBJ export does the same) and the render UV map, so the generated
    latents land in the texture space the material samples. No normals: the
    backend's reader (trimesh) merges corners that share position and UV and
    recomputes smooth vertex normals whatever the file says."""
    corners = _triangles(obj, slots)
    if corners is None:
        raise InputProblem(f"{obj.name!r}: no face with a UV map uses this material")
    pos, _, uv, _ = corners
    y_up = lambda a: np.stack([a[:, 0], a[:, 2], -a[:, 1]], 1)
    index = np.arange(1, len(pos) + 1).reshape(-1, 3)
    lines = [f"v {x:.7g} {y:.7g} {z:.7g}" for x, y, z in y_up(pos)]
    lines += [f"vt {u:.7g} {v:.7g}" for u, v in uv]
    lines += ["f " + " ".join(f"{i}/{i}" for i in tri) for tri in index.tolist()]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
