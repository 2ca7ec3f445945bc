"""The one Principled BSDF reader (``richmat_addon.blender.pbr_source``) under both policies, and the one unwrapper.

The add-on reads ``strict`` (a clear InputProblem), the farm ``lenient`` (the
socket's value and a note); on a material both can follow they must agree.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from richmat_addon.core.colour import LUMINANCE, srgb_to_linear

READ = r'''
import json
import bpy
import numpy as np
from richmat_addon.blender.pbr_source import InputProblem, load_pbr, read_sources


def material(name):
    mat = bpy.data.materials.new(name)
    return mat, mat.node_tree, mat.node_tree.nodes["Principled BSDF"]


def image(tree, path, colorspace="sRGB"):
    node = tree.nodes.new("ShaderNodeTexImage")
    node.image = bpy.data.images.load(path, check_existing=True)
    node.image.colorspace_settings.name = colorspace
    return node


def both(mat, max_size=None):
    """Each policy's maps (as lists) and notes, or the strict error."""
    out = {}
    for policy in ("strict", "lenient"):
        try:
            sources = read_sources(mat, policy)
            pbr = load_pbr(sources, max_size)
            out[policy] = {"maps": [np.asarray(m.value).tolist() for m in (pbr.base_color, pbr.roughness,
                                                                         pbr.metalness)],
                           "notes": sources.notes}
        except InputProblem as exc:
            out[policy] = {"error": str(exc)}
    return out


result = {}

# glTF importer layout: base colour texture, packed ORM through Separate Color times a factor,
# a colour image straight into Metallic (Blender takes its luminance).
mat, tree, p = material("textured")
tree.links.new(image(tree, BASE).outputs["Color"], p.inputs["Base Color"])
sep = tree.nodes.new("ShaderNodeSeparateColor")
tree.links.new(image(tree, ORM, "Non-Color").outputs["Color"], sep.inputs["Color"])
times = tree.nodes.new("ShaderNodeMath")
times.operation = "MULTIPLY"
times.inputs[1].default_value = 0.5
tree.links.new(sep.outputs["Green"], times.inputs[0])
tree.links.new(times.outputs[0], p.inputs["Roughness"])
tree.links.new(image(tree, ORM, "Non-Color").outputs["Color"], p.inputs["Metallic"])
result["textured"] = both(mat)
result["downscaled"] = both(mat, max_size=4)

mat, tree, p = material("procedural")
p.inputs["Base Color"].default_value = (0.1, 0.2, 0.3, 1.0)
tree.links.new(tree.nodes.new("ShaderNodeTexNoise").outputs["Color"], p.inputs["Base Color"])
result["procedural"] = both(mat)

mat, tree, p = material("missing")
p.inputs["Roughness"].default_value = 0.25
missing = image(tree, BASE)
missing.image = bpy.data.images.load(BASE, check_existing=False)
missing.image.filepath = GONE
tree.links.new(missing.outputs["Color"], p.inputs["Roughness"])
result["missing"] = both(mat)

mat, tree, p = material("diffuse only")
tree.nodes.remove(p)
tree.links.new(tree.nodes.new("ShaderNodeBsdfDiffuse").outputs[0], tree.nodes["Material Output"].inputs["Surface"])
mat.diffuse_color, mat.roughness, mat.metallic = (0.7, 0.6, 0.5, 1.0), 0.4, 0.0
result["no_principled"] = both(mat)

mat, tree, p = material("two principled")
p.inputs["Roughness"].default_value = 0.125
mix = tree.nodes.new("ShaderNodeMixShader")
tree.links.new(p.outputs[0], mix.inputs[1])
tree.links.new(tree.nodes.new("ShaderNodeBsdfPrincipled").outputs[0], mix.inputs[2])
tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
result["two_principled"] = both(mat)

print("RESULT " + json.dumps(result))
'''

UNWRAP = r'''
import json
import bpy
import numpy as np
from batch import bl_materials
from richmat_addon.blender.unwrap import unwrap

bpy.ops.wm.read_homefile(use_empty=True)
bpy.ops.mesh.primitive_monkey_add()
kept = unwrap(bpy.context.active_object)  # the add-on's way: the user's quads kept, the stretched ones counted
addon = {"faces": kept.faces, "stretched": kept.stretched, "message": kept.message("Suzanne")}
bpy.ops.object.delete()
bpy.ops.mesh.primitive_monkey_add()
mesh = bpy.context.active_object.data
while mesh.uv_layers:
    mesh.uv_layers.remove(mesh.uv_layers[0])
notes = bl_materials.unwrap_missing_uvs()
uv = np.empty(len(mesh.loops) * 2, np.float32)
mesh.uv_layers.active.uv.foreach_get("vector", uv)
corners = uv.reshape(-1, 3, 2)
area = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]) / 2
print("RESULT " + json.dumps({"notes": notes, "sides": sorted({len(f.vertices) for f in mesh.polygons}),
                              "layer": mesh.uv_layers.active.name, "render": mesh.uv_layers.active.active_render,
                              "uv_range": [float(uv.min()), float(uv.max())],
                              "degenerate": int((np.abs(area) < 1e-9).sum()), "addon": addon}))
'''


def test_both_policies_read_one_way_and_lenient_notes_what_strict_refuses(blender_run, tmp_path: Path):
    rng = np.random.default_rng(0)
    base, orm = rng.integers(0, 256, (6, 10, 3), np.uint8), rng.integers(0, 256, (6, 10, 3), np.uint8)
    Image.fromarray(base).save(tmp_path / "base.png")
    Image.fromarray(orm).save(tmp_path / "orm.png")
    paths = {"BASE": tmp_path / "base.png", "ORM": tmp_path / "orm.png", "GONE": tmp_path / "gone.png"}
    result = blender_run("".join(f"{k} = {str(v)!r}\n" for k, v in paths.items()) + READ)

    textured = result["textured"]
    assert textured["strict"] == {"maps": textured["lenient"]["maps"], "notes": []}
    colour, rough, metal = (np.asarray(m) for m in textured["strict"]["maps"])
    orm_f = orm / np.float32(255)
    assert np.allclose(colour, srgb_to_linear(base / np.float32(255)), atol=1e-6)
    assert np.allclose(rough[..., 0], orm_f[..., 1] * 0.5, atol=1e-6)
    assert np.allclose(metal[..., 0], orm_f @ np.float32(LUMINANCE), atol=1e-5)

    # 10 x 6 into 4: 4 x 4 blocks (the last ones partial), each the mean of its stored texels
    colour = np.asarray(result["downscaled"]["lenient"]["maps"][0])
    blocks = [[base[r:r + 4, c:c + 4].reshape(-1, 3).mean(0) for c in range(0, 10, 4)] for r in range(0, 6, 4)]
    assert np.allclose(colour, srgb_to_linear(np.float32(blocks) / 255), atol=1e-5)
    assert result["downscaled"]["lenient"]["notes"] == ["texture 'base.png' downscaled from 10x6 to 3x2",
                                                        "texture 'orm.png' downscaled from 10x6 to 3x2"]

    procedural = result["procedural"]
    assert "'procedural': Base Color is fed by the procedural node" in procedural["strict"]["error"]
    assert np.allclose(procedural["lenient"]["maps"][0], [0.1, 0.2, 0.3])
    [note] = procedural["lenient"]["notes"]
    assert "procedural node" in note and note.endswith("(Base Color socket value used)")

    missing = result["missing"]
    assert "is missing" in missing["strict"]["error"] and "gone.png" in missing["strict"]["error"]
    assert missing["lenient"]["maps"][1] == [0.25]
    assert "is missing" in missing["lenient"]["notes"][0] and "Roughness socket value used" in missing["lenient"]["notes"][0]

    no_principled = result["no_principled"]
    assert "no Principled BSDF" in no_principled["strict"]["error"]
    assert np.allclose(no_principled["lenient"]["maps"][0], [0.7, 0.6, 0.5])
    assert np.allclose(no_principled["lenient"]["maps"][1:], [[0.4], [0.0]])
    assert "viewport colour, roughness and metallic used" in no_principled["lenient"]["notes"][0]

    two = result["two_principled"]
    assert "2 Principled BSDFs" in two["strict"]["error"]
    assert two["lenient"]["maps"][1] == [0.125] and "read 'Principled BSDF'" in two["lenient"]["notes"][0]


def test_the_farm_unwraps_with_the_addon_unwrapper_triangulated(blender_run):
    unwrap = blender_run(UNWRAP)
    assert unwrap["notes"] == ["Suzanne: no UVs, unwrapped with xatlas"]
    assert unwrap["sides"] == [3]  # every face one chart triangle: no face stretched across two charts
    assert unwrap["layer"] == "richmat_uv" and unwrap["render"]
    assert 0.0 <= unwrap["uv_range"][0] and unwrap["uv_range"][1] <= 1.0 and unwrap["degenerate"] == 0
    # Suzanne's quads unwrapped as they are: some span two charts, and the user is told how many and what to do.
    addon = unwrap["addon"]
    assert addon["faces"] == 500 and 0 < addon["stretched"] < addon["faces"]
    assert f"{addon['stretched']} of 500 faces span two UV charts" in addon["message"]
    assert "Triangulate" in addon["message"]
