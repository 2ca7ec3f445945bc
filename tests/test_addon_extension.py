"""The Blender extension end to end: build, install into the pip bpy module, run every operator.

Each test runs one child process (``blender_run``) that installs the zip built by
``make extension`` into a temporary user folder, exactly as a user would, and
drives the operators headless on a procedural asset (real assets when
../shared/assets is present).
"""
from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def blender_ext() -> Path:
    """Blender's extension CLI, shipped inside the bpy wheel."""
    import importlib.util

    return Path(importlib.util.find_spec("bpy").origin).parent / "5.0/scripts/addons_core/bl_pkg/cli/blender_ext.py"


def build_extension() -> Path:
    """``make extension`` (the venv is not re-installed: its stamp is taken as up to date); the zip.
    Also used by bench/addon_assets.py."""
    subprocess.run(["make", "-o", ".venv/.installed", f"PY={sys.executable}", "extension"], cwd=REPO,
                   check=True, capture_output=True)
    zips = sorted((REPO / "dist").glob("richmat-*.zip"))
    assert zips, "make extension wrote no zip"
    return zips[-1]


@pytest.fixture(scope="session")
def extension_zip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_extension()


def script(body: str, zip_path: Path) -> str:
    return PRELUDE.format(zip=str(zip_path)) + "\n" + body


PRELUDE = r'''
import importlib, json, os, sys, time
from pathlib import Path
import numpy as np
import bpy, addon_utils

ZIP = {zip!r}
MODULE = "bl_ext.user_default.richmat"
# Install exactly as a user would: the built zip, into the temporary user folder.
assert bpy.ops.extensions.package_install_files(filepath=ZIP, repo="user_default",
                                                 enable_on_install=True) == {{"FINISHED"}}
addon_utils.enable(MODULE, default_set=True)
assert MODULE in bpy.context.preferences.addons
bpy.ops.wm.read_homefile(use_empty=True)
scene = bpy.context.scene
reports = []

def run_op(name, **kw):
    """Call bpy.ops.richmat.<name>; returns (result, messages) with reports captured from stdout."""
    op = getattr(bpy.ops.richmat, name)
    try:
        return op(**kw), None
    except RuntimeError as exc:  # ERROR reports raise in background mode
        return {{"CANCELLED"}}, str(exc)

def press(name, **kw):
    """Run an operator as a button does: (sorted result, the lines it reported), its reports read from
    stdout, where Blender prints them in background mode, and its error."""
    log = Path(bpy.app.tempdir or "/tmp") / f"{{name}}_{{os.getpid()}}.log"
    sys.stdout.flush()
    fd, saved = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC), os.dup(1)
    os.dup2(fd, 1)
    try:
        res, err = run_op(name, **kw)
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(fd), os.close(saved)
    return sorted(res), log.read_text() + (err or "")

def write_png(path, rgba):
    h, w, _ = rgba.shape
    img = bpy.data.images.new(Path(path).stem, w, h, alpha=True)
    img.pixels.foreach_set(np.ascontiguousarray(rgba[::-1], np.float32).ravel())
    img.filepath_raw = str(path)
    img.file_format = "PNG"
    img.save()
    bpy.data.images.remove(img)
    return str(path)

def procedural_asset(folder, size=64, name="painted"):
    """A UV sphere with a textured paint material: base colour, packed ORM (roughness G,
    metal B) through Separate Color, and a normal map chain."""
    folder = Path(folder)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16)
    obj = bpy.context.active_object
    bpy.ops.object.shade_smooth()
    obj.name = name
    y, x = np.mgrid[0:size, 0:size] / size
    base = np.stack([0.6 + 0.3 * np.sin(6 * x), 0.2 + 0.1 * y, 0.1 + 0 * x, 1 + 0 * x], -1)
    orm = np.stack([1 + 0 * x, 0.3 + 0.4 * y, 0 * x, 1 + 0 * x], -1)
    nrm = np.stack([0.5 + 0 * x, 0.5 + 0 * x, 1 + 0 * x, 1 + 0 * x], -1)
    mat = bpy.data.materials.new(name + "_mat")
    obj.data.materials.append(mat)
    tree = mat.node_tree
    p = tree.nodes["Principled BSDF"]
    def image_node(file, data):
        node = tree.nodes.new("ShaderNodeTexImage")
        node.image = bpy.data.images.load(write_png(folder / file, data))
        if data is not base:
            node.image.colorspace_settings.name = "Non-Color"
        return node
    b, o, n = image_node("base.png", base), image_node("orm.png", orm), image_node("normal.png", nrm)
    tree.links.new(b.outputs["Color"], p.inputs["Base Color"])
    sep = tree.nodes.new("ShaderNodeSeparateColor")
    tree.links.new(o.outputs["Color"], sep.inputs["Color"])
    tree.links.new(sep.outputs["Green"], p.inputs["Roughness"])
    tree.links.new(sep.outputs["Blue"], p.inputs["Metallic"])
    nm = tree.nodes.new("ShaderNodeNormalMap")
    nm.name = "normal_map"
    tree.links.new(n.outputs["Color"], nm.inputs["Color"])
    tree.links.new(nm.outputs["Normal"], p.inputs["Normal"])
    return obj

def render(size=32, samples=8):
    """A tiny CPU render with one area light; (H, W, 3) linear float."""
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    if scene.camera is None:
        cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
        cam.location = (0, -6, 1)
        cam.rotation_euler = (1.41, 0, 0)
        scene.collection.objects.link(cam)
        scene.camera = cam
        light = bpy.data.objects.new("light", bpy.data.lights.new("light", "AREA"))
        light.data.size = 1.0
        light.rotation_euler = (0.8, 0, 0.6)
        light.data.energy = 800
        light.location = (3, -4, 4)
        scene.collection.objects.link(light)
    path = Path(bpy.app.tempdir or "/tmp") / f"render_{{os.getpid()}}.exr"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(path))
    px = np.empty(size * size * 4, np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    return px.reshape(size, size, 4)[..., :3]
'''


def test_manifest_validates_and_zip_holds_the_addon(extension_zip: Path):
    out = subprocess.run([sys.executable, str(blender_ext()), "validate", str(extension_zip)],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
    names = zipfile.ZipFile(extension_zip).namelist()
    assert "blender_manifest.toml" in names and "__init__.py" in names
    assert "blender/operators.py" in names and "core/enhance.py" in names
    assert not any("__pycache__" in n or n.startswith("torch_models") for n in names)
    manifest = zipfile.ZipFile(extension_zip).read("blender_manifest.toml").decode()
    assert "[permissions]" in manifest and "files =" in manifest and "network" not in manifest


def test_uplift_bake_export_switch_on_a_procedural_asset(blender_run, extension_zip: Path, tmp_path: Path):
    result = blender_run(script(f'''
obj = procedural_asset({str(tmp_path)!r})
original = obj.active_material
before = render(64, 16)
scene.richmat.enhancement_type = "2"
scene.richmat.seed = 3
res, err = run_op("uplift_material")
assert res == {{"FINISHED"}}, err
enhanced = obj.active_material
enhanced_name = enhanced.name
nodes = {{n.name: n for n in enhanced.node_tree.nodes}}
links = [(l.from_node.name, l.to_node.name, l.to_socket.name) for l in enhanced.node_tree.links]
engine = (scene.render.engine, scene.cycles.device, scene.cycles.shading_system)
after = render(64, 16)
# Idempotent: a second uplift replaces its own material, the original stays untouched.
n_materials = len(bpy.data.materials)
assert run_op("uplift_material")[0] == {{"FINISHED"}}
again = len(bpy.data.materials)
# Edit one constant in place (the panel does exactly this), then bake.
obj.active_material.node_tree.nodes["const_coat_ior"].outputs[0].default_value = 1.7
scene.richmat.output_dir = {str(tmp_path / "baked")!r}
res, err = run_op("bake_parameters")
assert res == {{"FINISHED"}}, err
baked = obj.active_material
baked_dir = Path(baked.richmat.bake_dir)
files = sorted(p.name for p in baked_dir.iterdir())
params = importlib.import_module(MODULE + ".core.material_folder").read(baked_dir).record
baked_images = sorted(Path(n.image.filepath).name for n in baked.node_tree.nodes
                      if n.bl_idname == "ShaderNodeTexImage" and n.name.startswith("tex_"))
res, err = run_op("export_materialx", directory={str(tmp_path / "mtlx")!r})
assert res == {{"FINISHED"}}, err
assert run_op("switch_material")[0] == {{"FINISHED"}}
switched_to = obj.active_material.name
# The Richmat tab is registered in both editors' sidebars (the pip module has no window to draw in).
from bl_ext.user_default.richmat.blender import panels
assert hasattr(bpy.types, "RICHMAT_PT_view3d") and hasattr(bpy.types, "RICHMAT_PT_shader_editor")
assert panels.RICHMAT_PT_view3d.bl_category == panels.RICHMAT_PT_shader_editor.bl_category == "Richmat"
assert (panels.RICHMAT_PT_view3d.bl_space_type, panels.RICHMAT_PT_shader_editor.bl_space_type) == \
    ("VIEW_3D", "NODE_EDITOR")
print("RESULT " + json.dumps(dict(
    nodes=sorted(nodes), links=links, engine=engine,
    before=[float(before.mean()), float(before.max())], after=[float(after.mean()), float(after.max())],
    finite=bool(np.isfinite(after).all()), n_materials=n_materials, again=again,
    original_name=original.name, enhanced_name=enhanced_name, original_nodes=len(original.node_tree.nodes),
    files=files, params=params, baked_images=baked_images, switched_to=switched_to)))
''', extension_zip))
    assert result["enhanced_name"] == "painted_mat (richmat)" and result["switched_to"] == "painted_mat"
    assert result["original_nodes"] == 7  # principled, output, 3 images, separate colour, normal map
    assert result["n_materials"] == result["again"] == 2
    nodes = set(result["nodes"])
    assert {"richmat_osl", "richmat_native", "richmat_output", "richmat_output_eevee", "richmat_output_export",
            "normal_map", "tex_base_color", "const_coat_ior", "richmat_frame_coat", "richmat_frame_specular",
            "richmat_frame_original"} <= nodes
    for shader in ("richmat_osl", "richmat_native", "richmat_export"):  # normal chain reused unchanged
        assert ["normal_map", shader, "Normal"] in result["links"]
    # Uplift leaves the render settings alone; Cycles without OSL renders the native graph, EEVEE too.
    assert result["engine"] == ["CYCLES", "CPU", False]
    assert ["richmat_native", "richmat_output", "Surface"] in result["links"]
    assert ["richmat_native", "richmat_output_eevee", "Surface"] in result["links"]
    assert result["finite"]
    # Type 2 adds a sharp clearcoat highlight of the point light on a rough paint.
    assert result["after"][1] > 2 * result["before"][1], (result["before"], result["after"])
    assert {"params.json", "material.mtlx", "base_color.exr", "alpha_core.exr"} <= set(result["files"])
    params = result["params"]
    assert params["type"] == 2 and params["seed"] == 3
    assert params["constants"]["coat_ior"] == pytest.approx(1.7, abs=1e-6)  # the edit survives baking
    assert set(result["baked_images"]) <= set(result["files"])  # the material now uses the baked maps
    mtlx = tmp_path / "mtlx" / "painted_mat" / "material.mtlx"
    text = mtlx.read_text()
    assert 'value="alpha_core.exr"' in text and "/" not in text.split('value="alpha_core.exr"')[0][-40:]
