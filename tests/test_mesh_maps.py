"""World maps of a material's surfaces (``richmat_addon.blender.mesh_maps``), as the add-on and the batch use them.

A floor quad (left half of the UV square, facing +z) and a wall object (rotated
90 degrees about z and moved to x = 5) share a material; the wall's second slot
holds another material whose face overlaps the first's UVs, so texels only come
out right when slots are kept apart, object transforms applied and objects
combined.
"""
from __future__ import annotations

import numpy as np

SCENE = r'''
import json, math
import bpy
import numpy as np
from batch import bl_materials
from richmat_addon.blender import mesh_maps

bpy.ops.wm.read_homefile(use_empty=True)
shared, other = bpy.data.materials.new("shared"), bpy.data.materials.new("other")


def quads(name, faces, uvs, slots, materials, with_uvs=True):
    """One object of quads: faces as 4 corners each, uvs per corner, a material slot per face."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([c for f in faces for c in f], [], [tuple(range(4 * i, 4 * i + 4)) for i in range(len(faces))])
    for m in materials:
        mesh.materials.append(m)
    mesh.polygons.foreach_set("material_index", slots)
    if with_uvs:
        mesh.uv_layers.new(name="UVMap").data.foreach_set("uv", np.ravel(uvs).astype(np.float32))
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


LEFT = [(0, 0), (0.5, 0), (0.5, 1), (0, 1)]
RIGHT = [(0.5, 0), (1, 0), (1, 1), (0.5, 1)]
floor = quads("floor", [[(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]], [LEFT], [0], [shared])
wall = quads("wall", [[(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)],  # faces -y before the rotation
                      [(0, 0, 2), (1, 0, 2), (1, 1, 2), (0, 1, 2)]],  # faces +z, other material
             [RIGHT, RIGHT], [0, 1], [shared, other])
wall.rotation_euler.z = math.pi / 2
wall.location.x = 5.0
bare = quads("no_uvs", [[(0, 0, 9), (1, 0, 9), (1, 1, 9), (0, 1, 9)]], [LEFT], [0], [shared], with_uvs=False)
bpy.context.view_layer.update()


def maps(surfaces):
    normals, positions, reason = mesh_maps.world_maps(surfaces, (8, 16))
    if normals is None:
        return reason
    return {"normals": normals.value.tolist(), "positions": positions.value.tolist()}


print("RESULT " + json.dumps({
    "surfaces": [[o.name, s] for o, s in bl_materials.material_surfaces(shared)],
    "shared": maps(bl_materials.material_surfaces(shared)),
    "other": maps(bl_materials.material_surfaces(other)),
    "slot": maps([(wall, [1])]),
    "bare": maps([(bare, [0])]),
}))
'''


def test_world_maps_keep_slots_apart_apply_transforms_and_combine_objects(blender_run):
    result = blender_run(SCENE)
    assert result["surfaces"] == [["floor", [0]], ["wall", [0]], ["no_uvs", [0]]]
    shared = {k: np.array(v) for k, v in result["shared"].items()}
    left, right = np.s_[:, :6], np.s_[:, 10:]  # texels well inside each half of the UV square
    assert np.allclose(shared["normals"][left], (0, 0, 1), atol=1e-5)
    assert np.allclose(shared["positions"][left][..., 2], 0, atol=1e-5)
    assert np.allclose(shared["normals"][right], (1, 0, 0), atol=1e-5)  # -y turned by 90 degrees about z
    assert np.allclose(shared["positions"][right][..., 0], 5, atol=1e-5)
    assert shared["positions"][right][..., 2].min() > 0 and shared["positions"][right][..., 2].max() < 1

    for key in ("other", "slot"):  # the batch's surfaces of the other material = the add-on's one slot
        other = {k: np.array(v) for k, v in result[key].items()}
        assert np.allclose(other["normals"][right], (0, 0, 1), atol=1e-5)
        assert np.allclose(other["positions"][right][..., 2], 2, atol=1e-5)
        assert np.allclose(other["normals"][:, :2], 0)  # beyond the padding of its half: not covered
    assert result["bare"] == "no face with a UV map uses this material"
