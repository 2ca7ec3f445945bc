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

from support.extension import build_extension, script
from tools.blender_ext import cli_path


@pytest.fixture(scope="session")
def extension_zip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_extension()


def test_manifest_validates_and_zip_holds_the_addon(extension_zip: Path):
    out = subprocess.run([sys.executable, str(cli_path()), "validate", str(extension_zip)],
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
