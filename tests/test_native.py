"""The native node graph: its fits, its groups per type, its Cycles renders against OSL's, the farm's --graph."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from batch import options
from richmat_addon.core import albedo_fits, graph
from richmat_addon.core.closures import dielectric, sheen
from richmat_addon.core.enhance import enhance
from richmat_addon.core.enhancement_types import TYPES
from richmat_addon.core.maps import EnhancedMaterial, ParamMap, PbrInputs

from support.extension import script
from .test_addon_extension import extension_zip  # noqa: F401  (session fixture)
from .test_osl import BLENDER_PRELUDE, save_materials

REPO = Path(__file__).resolve().parents[1]
PROBE = REPO / "torch_models" / "data" / "studio_small_03_512.hdr"
FLIP_LIMIT = 0.05  # per type at 24 px and 16 samples; bench/material/native_agreement.py measures it properly


def type_material(type_: int, metal: bool = False) -> EnhancedMaterial:
    """A constant material of ``type_``, as the enhancement draws it."""
    pbr = PbrInputs(f"type{type_}{'_metal' if metal else ''}", ParamMap.constant(0.6, 0.3, 0.2),
                    ParamMap.constant(0.4), ParamMap.constant(1.0 if metal else 0.0))
    return enhance(pbr, type_, seed=1)


FIT_NODES = """
import json, math
import numpy as np
import bpy
from richmat_addon.blender.native_closures import dielectric as dielectric_nodes, sheen as sheen_nodes
from richmat_addon.blender.native_nodes import Builder

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.engine = "CYCLES"
scene.cycles.samples, scene.cycles.filter_width = 1, 0.01  # every sample inside its pixel
scene.cycles.use_denoising = False
scene.render.resolution_x = scene.render.resolution_y = SIZE
scene.render.threads_mode, scene.render.threads = "FIXED", 1
scene.view_settings.view_transform = "Standard"
scene.render.image_settings.file_format = "OPEN_EXR"
scene.render.image_settings.color_depth = "32"
bpy.ops.mesh.primitive_plane_add(size=4.0, rotation=(math.pi / 2, 0.0, 0.0))
cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
cam.data.type, cam.data.ortho_scale = "ORTHO", 2.0
cam.location, cam.rotation_euler = (0.0, -5.0, 0.0), (math.pi / 2, 0.0, 0.0)
scene.collection.objects.link(cam)
scene.camera = cam

out = {}
for ior in IORS:
    mat = bpy.data.materials.new("fit")
    tree = mat.node_tree
    tree.nodes.clear()
    b = Builder(tree)
    window = b.node("ShaderNodeSeparateXYZ")
    b.feed(window.inputs[0], b.node("ShaderNodeTexCoord").outputs["Window"])
    # One value per pixel, whatever the sample's position in it: the pixel's centre.
    mu, y = ((b.math("FLOOR", b.math("MULTIPLY", window.outputs[k], SIZE)) for k in (0, 1)))
    mu, y = (b.math("DIVIDE", b.math("ADD", v, 0.5), SIZE) for v in (mu, y))
    diel = b.group(dielectric_nodes.albedo_group(), Cosine=mu, Alpha=b.math("MULTIPLY", y, y), IOR=ior)
    sheen = b.group(sheen_nodes.albedo_group(), Cosine=mu, Roughness=y)
    rgb = b.node("ShaderNodeCombineXYZ")
    for k, socket in enumerate((diel.outputs["Albedo"], sheen.outputs["Albedo"])):
        b.feed(rgb.inputs[k], socket)
    emission = b.node("ShaderNodeEmission")
    b.feed(emission.inputs["Color"], rgb.outputs[0])
    b.feed(tree.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"], emission.outputs[0])
    bpy.data.objects["Plane"].data.materials.append(mat)
    bpy.data.objects["Plane"].active_material = mat
    scene.render.filepath = f"//fit_{ior}.exr"
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(bpy.path.abspath(scene.render.filepath))
    out[str(ior)] = np.array(img.pixels[:], np.float32).reshape(SIZE, SIZE, 4)[..., :3].tolist()
print("RESULT " + json.dumps(out))
"""


def test_the_fit_nodes_compute_the_core_fits(blender_run):
    """Emission of (A, R, 0) over a grid of (mu, sqrt(alpha) or roughness), one grid point per pixel."""
    size, iors = 16, [1.3, 1.5, 1.8]
    result = blender_run(f"SIZE, IORS = {size}, {iors!r}\n" + FIT_NODES)
    centres = (np.arange(size) + 0.5) / size
    for ior in iors:
        img = np.asarray(result[str(ior)])  # bottom row first: row index = y
        want = np.array([[[dielectric.fitted_albedo(m, y * y, ior), sheen.fitted_albedo(m, y), 0.0]
                          for m in centres] for y in centres])
        assert np.abs(img - want).max() < 1e-4, ior


PER_TYPE = BLENDER_PRELUDE + """
from support import blender_preview_scene as ball_scene

def trees(material):
    found, stack = [], [material.node_tree]
    while stack:
        tree = stack.pop()
        found.append(tree)
        stack += [n.node_tree for n in tree.nodes if n.type == "GROUP"]
    return found

out = {}
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
cycles_builder.enable_osl(scene)
ball_scene.setup(scene, PreviewScene(resolution=SIZE), PROBE, None, SAMPLES)
scene.render.threads_mode, scene.render.threads = "FIXED", 1
ball = bpy.data.node_groups[ball_scene.BALL].nodes["Set Material"].inputs["Material"]
for name in NAMES:
    row = out[name] = {}
    material = cycles_builder.build_material(load_material(NPZ, name), {}, name)
    ball.default_value = material
    native = material.node_tree.nodes[cycles_builder.NATIVE_NODE].node_tree
    row["lobe_nodes"] = sorted(n.label for n in native.nodes if n.type == "GROUP" and not n.label.startswith("layer"))
    row["groups"] = sorted({t.name for t in trees(material)[1:]})
    row["links_valid"] = all(link.is_valid for t in trees(material) for link in t.links)
    row["outputs"] = {n.name: [n.target, n.inputs["Surface"].links[0].from_node.name, n.is_active_output]
                      for n in material.node_tree.nodes if n.type == "OUTPUT_MATERIAL"}
    for which in ("osl", "native"):
        scene.cycles.shading_system = which == "osl"
        cycles_builder.use_in_cycles(material, which)
        ball_scene.render_exr(scene, Path(f"{name}_{which}.exr").resolve())
print("RESULT " + json.dumps(out))
"""


def test_each_type_builds_its_groups_and_renders_like_osl(blender_run, tmp_path: Path):
    from richmat_addon.core.folder_io import read_exr
    from torch_models.render.flip import flip_map
    from torch_models.render.tonemap import agx

    materials = {m.name: m for m in [type_material(t.index) for t in TYPES] + [type_material(2, metal=True)]}
    npz = save_materials(tmp_path / "materials.npz", materials)
    result = blender_run(f"from pathlib import Path\nNPZ, NAMES, PROBE = {npz!r}, {list(materials)!r}, "
                         f"Path({str(PROBE)!r})\nSIZE, SAMPLES = 24, 16\n" + PER_TYPE)
    for name, mat in materials.items():
        row = result[name]
        lobes = [lobe.name for lobe in graph.iter_lobes(graph.prune(graph.SURFACE, mat.constants()))]
        assert row["lobe_nodes"] == sorted(lobes), name
        assert row["links_valid"], name
        assert any(g.startswith("richmat native (") for g in row["groups"]), row["groups"]
        # EEVEE draws a Sheen BSDF as a diffuse, so a graph with a sheen lobe gets EEVEE's own form.
        eevee_form = any(lobe.closure == "sheen" for lobe in graph.iter_lobes(graph.prune(graph.SURFACE,
                                                                                        mat.constants())))
        assert row["outputs"]["richmat_output_eevee"][:2] == \
            ["EEVEE", "richmat_native_eevee" if eevee_form else "richmat_native"], name
        assert any(g.startswith("richmat native eevee (") for g in row["groups"]) == eevee_form, name
        assert row["outputs"]["richmat_output_export"] == ["ALL", "richmat_export", True]
        osl, native = (read_exr(tmp_path / f"{name}_{w}.exr") for w in ("osl", "native"))
        ball = native[..., 3] > 0.5
        rgb = native[..., :3][ball]
        assert np.isfinite(rgb).all() and rgb.mean() > 0.05, name  # lit, not black
        pink = (rgb[:, 0] > 0.8) & (rgb[:, 1] < 0.1) & (rgb[:, 2] > 0.8)
        assert pink.mean() < 0.01, name  # not Blender's missing-shader magenta
        _, flip = flip_map(agx(osl[..., :3]), agx(native[..., :3]))
        assert flip < FLIP_LIMIT, (name, flip)
    assert "richmat conductor v1" in result["type2_metal"]["groups"]
    assert "richmat tinted dielectric v1" in result["type5"]["groups"]


def test_the_farm_takes_the_graph_and_hashes_it():
    parser = options.build_parser()
    base = ["--input", "in", "--output", "out"]
    osl, native = (options.settings_of(parser.parse_args(base + ["--graph", g])) for g in ("osl", "native"))
    assert options.settings_of(parser.parse_args(base)).graph == "native"  # on every device, the CPU too
    assert native.graph == "native" and native.hash() != osl.hash()  # the beauty frames differ
    with pytest.raises(SystemExit):
        parser.parse_args(base + ["--graph", "svm"])


@pytest.mark.parametrize("option, choices, default", [
    ("denoise_prefilter", options.DENOISE_PREFILTERS, "fast"),
    ("denoise_quality", options.DENOISE_QUALITIES, "high")])
def test_the_farm_takes_the_denoiser_settings_and_hashes_them(option: str, choices: tuple[str, ...],
                                                               default: str) -> None:
    """OIDN's prefilter and network default to what bench/farm/beauty_denoise.py chose; every other
    choice renders other frames, so it is another settings hash."""
    parser = options.build_parser()
    base = ["--input", "in", "--output", "out"]
    flag = "--" + option.replace("_", "-")
    assert getattr(parser.parse_args(base), option) == default
    settings = [options.settings_of(parser.parse_args(base + [flag, c])) for c in choices]
    assert [getattr(s, option) for s in settings] == list(choices)
    assert len({s.hash() for s in settings}) == len(choices)
    with pytest.raises(SystemExit):
        parser.parse_args(base + [flag, "none"])


ADDON_BALL = r'''
bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16)
bpy.ops.object.shade_smooth()
obj = bpy.context.active_object
material = bpy.data.materials.new("paint")
obj.data.materials.append(material)
principled = material.node_tree.nodes["Principled BSDF"]
principled.inputs["Base Color"].default_value = (0.6, 0.3, 0.2, 1.0)
principled.inputs["Roughness"].default_value = 0.4
scene.richmat.enhancement_type = "3"  # dust and a coat: a sheen and a clearcoat to export
builder = importlib.import_module(MODULE + ".blender.cycles_builder")
'''

TOGGLE = ADDON_BALL + r'''
scene.render.engine = "CYCLES"  # the artist's choice: Cycles without OSL (as on a GPU without OptiX)
before = (scene.render.engine, scene.cycles.device, scene.cycles.shading_system)
res, _ = run_op("uplift_material")
enhanced = obj.active_material
after = (scene.render.engine, scene.cycles.device, scene.cycles.shading_system)
out = {"uplift": list(res), "engine": [list(before), list(after)], "graphs": [builder.cycles_graph(enhanced)]}
native = render(24, 8)
prefs = bpy.context.preferences.addons["cycles"].preferences
prefs.compute_device_type, scene.cycles.device = "CUDA", "GPU"  # a GPU that cannot run OSL: refused
res, err = run_op("toggle_cycles_graph")
out["refused"] = [sorted(res), err, scene.cycles.shading_system]
out["graphs"].append(builder.cycles_graph(enhanced))
prefs.compute_device_type, scene.cycles.device = "NONE", "CPU"  # the CPU: the toggle turns OSL on itself
out["toggled"] = list(run_op("toggle_cycles_graph")[0])
out["osl_on"] = [scene.render.engine, scene.cycles.device, scene.cycles.shading_system]
out["graphs"].append(builder.cycles_graph(enhanced))
osl = render(24, 8)
scene.cycles.shading_system = False  # OSL off again: the handler must not leave a black material
bpy.context.view_layer.update()
out["graphs"].append(builder.cycles_graph(enhanced))
out["means"] = [float(native.mean()), float(osl.mean())]
print("RESULT " + json.dumps(out))
'''


def test_uplift_keeps_the_engine_and_the_toggle_never_leaves_black(blender_run, extension_zip: Path):  # noqa: F811
    result = blender_run(script(TOGGLE, extension_zip))
    assert result["uplift"] == ["FINISHED"]
    assert result["engine"][0] == result["engine"][1] == ["CYCLES", "CPU", False]
    # Cycles without OSL: native; refused on CUDA (naming the switch, nothing changed); on the CPU the
    # toggle turns OSL on (engine and device kept) and Cycles reads OSL; OSL off again: native.
    assert result["graphs"] == ["native", "native", "osl", "native"]
    assert result["refused"][0] == ["CANCELLED"] and result["refused"][2] is False
    assert "CUDA" in result["refused"][1] and "Device to CPU" in result["refused"][1]
    assert result["toggled"] == ["FINISHED"] and result["osl_on"] == ["CYCLES", "CPU", True]
    native, osl = result["means"]
    assert native > 0.01 and osl > 0.01 and abs(native - osl) < 0.1 * osl


GLTF = ADDON_BALL + r'''
assert run_op("uplift_material")[0] == {"FINISHED"}
constants = {n.name[len("const_"):]: (list(n.outputs[0].default_value)[:3] if n.type == "RGB"
                                       else n.outputs[0].default_value)
             for n in obj.active_material.node_tree.nodes if n.name.startswith("const_")}
path = str(Path(TMP) / "ball.gltf")
assert bpy.ops.export_scene.gltf(filepath=path, export_format="GLTF_SEPARATE") == {"FINISHED"}
document = json.loads(Path(path).read_text())
bpy.ops.wm.read_homefile(use_empty=True)
assert bpy.ops.import_scene.gltf(filepath=path) == {"FINISHED"}
imported = next(o for o in bpy.data.objects if o.type == "MESH").active_material
p = next(n for n in imported.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
values = {s.name: (list(s.default_value)[:3] if s.type == "RGBA" else s.default_value) for s in p.inputs
          if s.type in ("RGBA", "VALUE")}
print("RESULT " + json.dumps({"constants": constants, "values": values,
                              "extensions": document.get("extensionsUsed", [])}))
'''


def test_gltf_export_writes_the_native_materials_principled_values(blender_run, extension_zip: Path,  # noqa: F811
                                                                    tmp_path: Path):
    result = blender_run(script(f"TMP = {str(tmp_path)!r}\n" + GLTF, extension_zip))
    c, v = result["constants"], result["values"]
    assert {"KHR_materials_clearcoat", "KHR_materials_sheen", "KHR_materials_specular"} <= set(result["extensions"])
    expected = {"Base Color": c["base_color"], "Metallic": 0.0, "Roughness": math.sqrt(c["alpha_core"]),
                "Coat Weight": c["coat_weight"], "Coat Roughness": math.sqrt(c["coat_alpha"]),
                "Sheen Weight": 1.0, "Sheen Tint": [c["dust_weight"]] * 3, "Sheen Roughness": c["dust_roughness"]}
    for name, want in expected.items():
        assert v[name] == pytest.approx(want, abs=2e-3), name
    # The dielectric's F0 (Blender: F0(IOR) x 2 x level x tint) is the material's, whatever the IOR carries.
    f0 = albedo_fits.f0(v["IOR"]) * 2 * v["Specular IOR Level"] * np.mean(v["Specular Tint"])
    assert f0 == pytest.approx(albedo_fits.f0(c["diel_ior"]), rel=1e-3)


USD = r'''
bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16)
obj = bpy.context.active_object
material = bpy.data.materials.new("painted")
obj.data.materials.append(material)
image = bpy.data.images.new("stripes", 16, 16)
pixels = np.zeros((16, 16, 4), np.float32)
pixels[..., 3] = 1.0
pixels[:, ::2, 0] = 0.8  # red stripes: a texture, not a constant
pixels[:, 1::2, 2] = 0.6
image.pixels = pixels.ravel()
image.filepath_raw = str(Path(TMP) / "stripes.png")
image.file_format = "PNG"
image.save()
tree = material.node_tree
texture = tree.nodes.new("ShaderNodeTexImage")
texture.image = image
tree.links.new(texture.outputs["Color"], tree.nodes["Principled BSDF"].inputs["Base Color"])
scene.richmat.enhancement_type = "2"
assert run_op("uplift_material")[0] == {"FINISHED"}
enhanced = obj.active_material
out = Path(TMP) / "usd"
assert bpy.ops.wm.usd_export(filepath=str(out / "ball.usda"), export_materials=True, generate_preview_surface=True,
                             export_textures_mode="NEW") == {"FINISHED"}
print("RESULT " + json.dumps({"material": enhanced.name, "usda": (out / "ball.usda").read_text(),
                              "textures": sorted(p.name for p in (out / "textures").iterdir())}))
'''


def test_usd_export_keeps_the_enhanced_materials_textures(blender_run, extension_zip: Path,  # noqa: F811
                                                          tmp_path: Path):
    """USD's exporter reads the export output's Principled BSDF: its base colour stays a
    texture (the enhanced material's, as read from the original), written beside the file and
    bound in a UsdPreviewSurface; the coat reaches it too."""
    result = blender_run(script(f"TMP = {str(tmp_path)!r}\n" + USD, extension_zip))
    usda = result["usda"]
    assert result["material"].endswith("(richmat)") and "UsdPreviewSurface" in usda
    assert result["textures"], "no texture written beside the USD file"
    for name in result["textures"]:
        assert name in usda  # every written texture is referenced by the material network
    assert "inputs:diffuseColor.connect" in usda  # the base colour is a texture, not a constant
    assert "float inputs:clearcoat = 1" in usda  # Type 2's coat
