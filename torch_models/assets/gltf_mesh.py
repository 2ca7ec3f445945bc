"""World-space triangle geometry of a glTF file, grouped per material (numpy only).

Dust depends on world-space normals, so the UV rasteriser needs, per material, the
triangles of every primitive that uses it, placed by the node hierarchy of the
default scene (a mesh instanced twice contributes twice). Points and lines are
skipped; strips and fans become triangle lists.

World space is the project's (Blender's) Z-up frame, as Blender's glTF importer
makes it: glTF (x, y, z) with +Y up becomes (x, -z, y). "Upward faces get dust"
then means the same thing for the backend and the add-on.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterator, Mapping

import numpy as np

from .gltf_container import GltfDocument

_COMPONENT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16,
              5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_TRIANGLES, _STRIP, _FAN = 4, 5, 6
GLTF_TO_Z_UP = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])


@dataclass
class MeshGeometry:
    """Triangles of one material in world space.

    ``uvs`` is None when none of the material's primitives has the UV set;
    primitives without it are left out when others have it (see ``notes``).
    """

    positions: np.ndarray  # (N, 3) float32
    normals: np.ndarray  # (N, 3) float32, unit length
    uvs: np.ndarray | None  # (N, 2) float32, glTF convention (origin top-left)
    indices: np.ndarray  # (M, 3) int64
    notes: list[str] = field(default_factory=list)


def read_accessor(doc: GltfDocument, index: int) -> np.ndarray:
    """An accessor as an (count, width) array; normalised integers become float32."""
    acc = doc.item("accessors", index, "a primitive")
    dtype = np.dtype(_COMPONENT.get(acc.get("componentType"), np.void)).newbyteorder("<")
    width = _WIDTH.get(acc.get("type"))
    if dtype.kind == "V" or width is None:
        raise doc.error(f"accessors[{index}] has an unknown componentType/type "
                        f"({acc.get('componentType')}, {acc.get('type')})")
    count = int(acc["count"])
    out = np.zeros((count, width), dtype)
    if "bufferView" in acc:
        view = doc.buffer_view(acc["bufferView"], f"accessors[{index}]")
        stride = int(doc.json["bufferViews"][acc["bufferView"]].get("byteStride") or dtype.itemsize * width)
        offset = int(acc.get("byteOffset", 0))
        needed = offset + (count - 1) * stride + dtype.itemsize * width if count else 0
        if needed > len(view):
            raise doc.error(f"accessors[{index}] needs {needed} bytes of bufferView "
                            f"{acc['bufferView']}, which has {len(view)} (truncated file?)")
        out[:] = np.ndarray((count, width), dtype, view, offset, (stride, dtype.itemsize))
    if "sparse" in acc:
        _apply_sparse(doc, index, acc["sparse"], out)
    if acc.get("normalized") and dtype.kind in "iu":
        info = np.iinfo(dtype)
        return np.maximum(out.astype(np.float32) / info.max, -1.0)
    return out


def _apply_sparse(doc: GltfDocument, index: int, sparse: dict[str, Any], out: np.ndarray) -> None:
    n = int(sparse["count"])
    where = f"accessors[{index}].sparse"
    idx_info, val_info = sparse["indices"], sparse["values"]
    idx_view = doc.buffer_view(idx_info["bufferView"], where)
    idx = np.frombuffer(idx_view, np.dtype(_COMPONENT[idx_info["componentType"]]).newbyteorder("<"),
                        n, int(idx_info.get("byteOffset", 0)))
    val_view = doc.buffer_view(val_info["bufferView"], where)
    vals = np.frombuffer(val_view, out.dtype, n * out.shape[1], int(val_info.get("byteOffset", 0)))
    if n and idx.max() >= len(out):
        raise doc.error(f"{where} indexes past the accessor's {len(out)} elements")
    out[idx] = vals.reshape(n, out.shape[1])


def _local_matrix(node: dict[str, Any]) -> np.ndarray:
    if "matrix" in node:
        return np.asarray(node["matrix"], np.float64).reshape(4, 4).T  # column-major in glTF
    x, y, z, w = node.get("rotation", (0.0, 0.0, 0.0, 1.0))
    rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = rot * np.asarray(node.get("scale", (1.0, 1.0, 1.0)))
    m[:3, 3] = node.get("translation", (0.0, 0.0, 0.0))
    return m


def mesh_instances(doc: GltfDocument) -> Iterator[tuple[int, np.ndarray]]:
    """(mesh index, 4x4 world matrix) for every mesh node of the default scene.

    Without scenes, every root node counts. Cycles in the hierarchy are an error.
    """
    nodes = doc.json.get("nodes", [])
    scenes = doc.json.get("scenes", [])
    if scenes:
        roots = doc.item("scenes", doc.json.get("scene", 0), "the file").get("nodes", [])
    else:
        children = {c for n in nodes for c in n.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    stack = [(r, np.eye(4), frozenset()) for r in roots]
    while stack:
        i, parent, seen = stack.pop()
        node = doc.item("nodes", i, "a scene")
        if i in seen:
            raise doc.error(f"nodes[{i}] is its own ancestor")
        world = parent @ _local_matrix(node)
        if "mesh" in node:
            doc.item("meshes", node["mesh"], f"nodes[{i}]")
            yield node["mesh"], world
        stack.extend((c, world, seen | {i}) for c in node.get("children", []))


def _triangles(doc: GltfDocument, prim: dict[str, Any], n_vertices: int) -> np.ndarray | None:
    mode = prim.get("mode", _TRIANGLES)
    if mode not in (_TRIANGLES, _STRIP, _FAN):
        return None
    idx = (read_accessor(doc, prim["indices"])[:, 0].astype(np.int64) if "indices" in prim
           else np.arange(n_vertices, dtype=np.int64))
    if idx.size and (idx.max() >= n_vertices):
        raise doc.error(f"a primitive indexes vertex {idx.max()} of {n_vertices}")
    if mode == _TRIANGLES:
        return idx[: len(idx) // 3 * 3].reshape(-1, 3)
    k = np.arange(max(len(idx) - 2, 0))
    if mode == _FAN:
        return np.stack([np.full_like(k, idx[0] if len(idx) else 0), idx[k + 1], idx[k + 2]], axis=1)
    odd = k % 2 == 1  # strips alternate winding
    return np.stack([idx[k], np.where(odd, idx[k + 2], idx[k + 1]), np.where(odd, idx[k + 1], idx[k + 2])], axis=1)


def _flat_normals(positions: np.ndarray, tris: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """glTF says: no NORMAL means flat shading, so unweld and use face normals."""
    flat = tris.reshape(-1)
    p = positions[tris]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    return flat, np.repeat(n, 3, axis=0), np.arange(len(flat)).reshape(-1, 3)


def _unit(v: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(v, axis=1, keepdims=True)
    return (v / np.where(length > 0, length, 1.0)).astype(np.float32)


def read_geometry(doc: GltfDocument, uv_sets: Mapping[int | None, int] | None = None
                  ) -> dict[int | None, MeshGeometry]:
    """World-space (Z-up) triangles per material index (None = glTF's default material).

    ``uv_sets`` picks the TEXCOORD_n set per material (default 0), i.e. the set its
    textures use (``GltfMaterial.placement.tex_coord``).
    """
    with doc.checked():
        return _read_geometry(doc, uv_sets or {})


def _read_geometry(doc: GltfDocument, uv_sets: Mapping[int | None, int]) -> dict[int | None, MeshGeometry]:
    parts: dict[int | None, list[tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]]] = {}
    for mesh_index, gltf_world in mesh_instances(doc):
        world = GLTF_TO_Z_UP @ gltf_world
        if abs(np.linalg.det(world[:3, :3])) < 1e-12:
            continue  # a zero scale hides the instance (a common glTF idiom): no surface
        normal_matrix = np.linalg.inv(world[:3, :3]).T
        for prim in doc.json["meshes"][mesh_index].get("primitives", []):
            attrs = prim.get("attributes", {})
            if "POSITION" not in attrs:
                continue
            material = prim.get("material")
            pos = read_accessor(doc, attrs["POSITION"]).astype(np.float64)
            tris = _triangles(doc, prim, len(pos))
            if tris is None or not len(tris):
                continue
            uv_name = f"TEXCOORD_{uv_sets.get(material, 0)}"
            uv = read_accessor(doc, attrs[uv_name]).astype(np.float32) if uv_name in attrs else None
            if "NORMAL" in attrs:
                nrm = read_accessor(doc, attrs["NORMAL"]).astype(np.float64)
            else:
                keep, nrm, tris = _flat_normals(pos, tris)
                pos, uv = pos[keep], None if uv is None else uv[keep]
            world_pos = pos @ world[:3, :3].T + world[:3, 3]
            parts.setdefault(material, []).append(
                (world_pos, nrm @ normal_matrix.T, uv, tris))
    return {m: _merge(p) for m, p in parts.items()}


def _merge(parts: list[tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]]) -> MeshGeometry:
    """Concatenate primitives; with mixed UV presence keep only those with UVs."""
    notes: list[str] = []
    with_uv = [p for p in parts if p[2] is not None]
    if with_uv and len(with_uv) < len(parts):
        notes.append(f"{len(parts) - len(with_uv)} of {len(parts)} primitives have no UVs and are "
                     f"left out of texture-space data")
        parts = with_uv
    offsets = np.cumsum([0] + [len(p[0]) for p in parts[:-1]])
    return MeshGeometry(
        positions=np.concatenate([p[0] for p in parts]).astype(np.float32),
        normals=_unit(np.concatenate([p[1] for p in parts])),
        uvs=np.concatenate([p[2] for p in parts]) if with_uv else None,  # type: ignore[misc]
        indices=np.concatenate([p[3] + o for p, o in zip(parts, offsets)]),
        notes=notes,
    )
