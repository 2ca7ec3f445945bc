"""Uplift's input handling: every bad input is one clear report and changes nothing; 4K stays fast."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from support.extension import script
from .test_addon_extension import extension_zip  # noqa: F401  (session fixture)

BAD_INPUTS = r'''
def snapshot():
    return (len(bpy.data.materials), len(bpy.data.images), len(bpy.data.texts),
            [s.material.name if s.material else None for s in bpy.context.active_object.material_slots])

def refused(setup):
    """Run uplift on the object setup() prepares; the error text, and whether nothing changed."""
    bpy.ops.wm.read_homefile(use_empty=True)
    setup()
    before = snapshot()
    res, err = run_op("uplift_material")
    assert res == {"CANCELLED"}, (setup.__name__, res)
    return err, snapshot() == before

def with_node(kind, socket="Base Color", configure=lambda node: None):
    def setup():
        obj = procedural_asset(TMP)
        tree = obj.active_material.node_tree
        node = tree.nodes.new(kind)
        configure(node)
        tree.links.new(node.outputs[0], tree.nodes["Principled BSDF"].inputs[socket])
    setup.__name__ = kind
    return setup

def no_principled():
    obj = procedural_asset(TMP)
    tree = obj.active_material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    tree.links.new(diffuse.outputs[0], tree.nodes["Material Output"].inputs["Surface"])

def image_from(path):
    """An image datablock pointing at a file, as a .blend saved elsewhere would hold it."""
    def configure(node):
        node.image = bpy.data.images.new(Path(path).stem, 8, 8)
        node.image.source = "FILE"
        node.image.filepath = path
    return configure

def udim(node):
    node.image = bpy.data.images.new("tiles", 32, 32, tiled=True)

def no_uvs():
    obj = procedural_asset(TMP)
    while obj.data.uv_layers:
        obj.data.uv_layers.remove(obj.data.uv_layers[0])

def linked_material():
    lib = Path(TMP) / "library.blend"
    if not lib.exists():
        mat = bpy.data.materials.new("libmat")
        bpy.data.libraries.write(str(lib), {mat})
        bpy.data.materials.remove(mat)
    obj = procedural_asset(TMP)
    with bpy.data.libraries.load(str(lib), link=True) as (src, dst):
        dst.materials = ["libmat"]
    obj.material_slots[0].material = dst.materials[0]

def metal_type4():
    obj = procedural_asset(TMP)
    p = obj.active_material.node_tree.nodes["Principled BSDF"]
    obj.active_material.node_tree.links.remove(p.inputs["Metallic"].links[0])
    p.inputs["Metallic"].default_value = 1.0
    bpy.context.scene.richmat.enhancement_type = "4"

garbage = Path(TMP) / "garbage.png"
garbage.write_bytes(b"not an image at all")
cases = dict(
    no_principled=no_principled,
    procedural=with_node("ShaderNodeTexNoise"),
    procedural_roughness=with_node("ShaderNodeValToRGB", "Roughness"),
    missing=with_node("ShaderNodeTexImage", configure=image_from(str(Path(TMP) / "gone.png"))),
    unreadable=with_node("ShaderNodeTexImage", configure=image_from(str(garbage))),
    udim=with_node("ShaderNodeTexImage", configure=udim),
    no_uvs=no_uvs,
    linked=linked_material,
    metal_type4=metal_type4,
)
out = {name: refused(setup) for name, setup in cases.items()}

# The fixes the reports name work: unwrap with xatlas, then uplift succeeds.
bpy.ops.wm.read_homefile(use_empty=True)
no_uvs()
unwrap = run_op("unwrap_uvs")
uplift_after_unwrap = run_op("uplift_material")

# A stock Blender has no xatlas: Unwrap falls back to Smart UV Project, keeping the face selection.
bpy.ops.wm.read_homefile(use_empty=True)
no_uvs()
mesh = bpy.context.active_object.data
mesh.polygons[0].select = False
selected = [p.select for p in mesh.polygons]
sys.modules["xatlas"] = None  # import xatlas now raises ImportError
smart = run_op("unwrap_uvs")
del sys.modules["xatlas"]
uv = np.array([d.vector[:] for d in mesh.uv_layers.active.uv]) if mesh.uv_layers.active else np.full((1, 2), np.nan)
smart_uvs = dict(name=mesh.uv_layers.active.name if mesh.uv_layers.active else None,
                 render=bool(mesh.uv_layers.active and mesh.uv_layers.active.active_render),
                 lo=float(np.nanmin(uv)), hi=float(np.nanmax(uv)), finite=bool(np.isfinite(uv).all()),
                 distinct=len(np.unique(uv.round(4), axis=0)),
                 selection_kept=[p.select for p in mesh.polygons] == selected)
uplift_after_smart = run_op("uplift_material")

# Poll: no mesh selected greys every button out.
bpy.ops.wm.read_homefile(use_empty=True)
bpy.ops.object.empty_add()
polls = {name: getattr(bpy.ops.richmat, name).poll() for name in
         ("uplift_material", "bake_parameters", "fit_neural", "export_materialx", "switch_material")}
print("RESULT " + json.dumps(dict(cases=out, unwrap=[list(unwrap[0]), unwrap[1]],
                                  uplift_after_unwrap=[list(uplift_after_unwrap[0]), uplift_after_unwrap[1]],
                                  smart=[list(smart[0]), smart[1]], smart_uvs=smart_uvs,
                                  uplift_after_smart=[list(uplift_after_smart[0]), uplift_after_smart[1]],
                                  polls=polls)))
'''

EXPECTED = {
    "no_principled": "no Principled BSDF",
    "procedural": "procedural node",
    "procedural_roughness": "bake it to an image texture first",
    "missing": "is missing",
    "unreadable": "cannot be read",
    "udim": "UDIM",
    "no_uvs": "no UV map",
    "linked": "linked from",
    "metal_type4": "dielectrics",
}


def test_every_bad_input_is_reported_and_changes_nothing(blender_run, extension_zip: Path,  # noqa: F811
                                                         tmp_path: Path):
    result = blender_run(script(f"TMP = {str(tmp_path)!r}\n" + BAD_INPUTS, extension_zip))
    for name, (message, unchanged) in result["cases"].items():
        assert message and EXPECTED[name] in message, (name, message)
        assert unchanged, name
    assert result["unwrap"][0] == ["FINISHED"], result["unwrap"]
    assert result["uplift_after_unwrap"][0] == ["FINISHED"], result["uplift_after_unwrap"]
    # without xatlas: Smart UV Project's map, in the unit square, active for rendering; uplift then works
    assert result["smart"][0] == ["FINISHED"], result["smart"]
    uvs = result["smart_uvs"]
    assert uvs["name"] == "richmat_uv" and uvs["render"] and uvs["finite"], uvs
    assert -1e-4 <= uvs["lo"] and uvs["hi"] <= 1 + 1e-4 and uvs["distinct"] > 8, uvs
    assert uvs["selection_kept"], uvs
    assert result["uplift_after_smart"][0] == ["FINISHED"], result["uplift_after_smart"]
    assert not any(result["polls"].values()), result["polls"]


def _gradient_png(path: Path, size: int, channels: tuple[float, float, float]) -> None:
    ramp = np.linspace(0.0, 1.0, size, dtype=np.float32)
    img = np.stack([c * (0.5 + 0.5 * ramp[None, :] * ramp[:, None]) for c in channels], -1)
    Image.fromarray((img * 255).astype(np.uint8)).save(path, compress_level=1)


def test_uplift_of_a_4k_material_works_at_preview_size(blender_run, extension_zip: Path,  # noqa: F811
                                                      tmp_path: Path):
    """Uplift stays interactive on 4K inputs by what it computes, counted (seconds on a shared
    machine would measure the neighbours): each file decoded once by OpenImageIO (not Blender's
    67-million-float pixel copy) and kept at 512, the enhancement and the mesh raster at 512."""
    _gradient_png(tmp_path / "base4k.png", 4096, (0.8, 0.4, 0.2))
    _gradient_png(tmp_path / "orm4k.png", 4096, (1.0, 0.7, 0.3))
    result = blender_run(script(f'''
import importlib
uplift = importlib.import_module(MODULE + ".blender.uplift")
pbr_source = importlib.import_module(MODULE + ".blender.pbr_source")
cost = {{"decoded": [], "blender_reads": 0, "enhanced": [], "rasterised": []}}
real = (pbr_source.image_pixels, pbr_source._read_with_blender, uplift.enhance, uplift.mesh_maps.world_maps)

def image_pixels(image, max_size=None, notes=None):
    px = real[0](image, max_size, notes)
    cost["decoded"].append(list(px.shape[:2]))
    return px

def read_with_blender(image):
    cost["blender_reads"] += 1
    return real[1](image)

def enhance(pbr, *args, **kwargs):
    cost["enhanced"].append(sorted({{tuple(m.shape) for m in (pbr.base_color, pbr.roughness, pbr.metalness)}}))
    return real[2](pbr, *args, **kwargs)

def world_maps(objects, size):
    cost["rasterised"].append(list(size))
    return real[3](objects, size)

pbr_source.image_pixels, pbr_source._read_with_blender = image_pixels, read_with_blender
uplift.enhance, uplift.mesh_maps.world_maps = enhance, world_maps
obj = procedural_asset({str(tmp_path)!r})
tree = obj.active_material.node_tree
for node in tree.nodes:
    if node.bl_idname == "ShaderNodeTexImage" and node.image.name.startswith("base"):
        node.image = bpy.data.images.load({str(tmp_path / "base4k.png")!r})
    elif node.bl_idname == "ShaderNodeTexImage" and node.image.name.startswith("orm"):
        node.image = bpy.data.images.load({str(tmp_path / "orm4k.png")!r})
        node.image.colorspace_settings.name = "Non-Color"
scene.richmat.enhancement_type = "3"  # dust + coat: masks and the mesh rasterised too
res, err = run_op("uplift_material")
assert res == {{"FINISHED"}}, err
sizes = sorted({{tuple(n.image.size) for n in obj.active_material.node_tree.nodes
                 if n.bl_idname == "ShaderNodeTexImage" and n.name.startswith("tex_")}})
print("RESULT " + json.dumps(dict(cost, sizes=sizes)))
''', extension_zip))
    assert result["sizes"] == [[512, 512]]  # preview maps; Bake writes the full 4K
    assert result["decoded"] == [[512, 512], [512, 512]], result  # base colour, packed ORM: once each
    assert result["blender_reads"] == 0, result
    assert result["enhanced"] == [[[512, 512]]], result
    assert result["rasterised"] == [[512, 512]], result
