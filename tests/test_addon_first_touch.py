"""Every button of the Richmat tab pressed once in Blender's default scene, as an artist first meets it."""
from __future__ import annotations

from pathlib import Path

from .test_addon_extension import extension_zip, script  # noqa: F401  (session fixture)

WALK = r'''
import tempfile
tempfile.tempdir = TMP  # where an unsaved file's Bake goes: the test's folder, not the machine's /tmp
bpy.ops.wm.read_factory_settings(use_empty=False)  # the default cube, EEVEE, Cycles on the CPU with OSL off
addon_utils.enable(MODULE, default_set=True)
scene = bpy.context.scene
bpy.context.view_layer.objects.active = bpy.data.objects["Cube"]
start = [scene.render.engine, scene.cycles.device, scene.cycles.shading_system, bpy.data.filepath]
scene.richmat.fit_steps = 5

pressed = {}
for name, kw in (("uplift_material", {}), ("switch_material", {}), ("switch_material", {}),
                 ("bake_parameters", {}), ("fit_neural", {}), ("preview_neural", {}), ("unwrap_uvs", {}),
                 ("export_materialx", {"directory": TMP + "/mtlx"})):
    pressed.setdefault(name, []).append(press(name, **kw))
unsaved = Path(TMP) / "richmat_unsaved"
print("RESULT " + json.dumps(dict(
    start=start, end=[scene.render.engine, scene.cycles.device, scene.cycles.shading_system],
    pressed=pressed, baked=sorted(p.name for p in unsaved.glob("*/*")) if unsaved.is_dir() else [])))
'''


def test_every_button_in_the_default_scene_finishes(blender_run, extension_zip: Path, tmp_path: Path):  # noqa: F811
    """Blender's default scene (EEVEE; Cycles on the CPU, OSL off; an unsaved file): no button ends in an
    error the add-on can resolve. Bake picks a folder itself, Preview turns OSL on and names the engine."""
    result = blender_run(script(f"TMP = {str(tmp_path)!r}\n" + WALK, extension_zip))
    assert result["start"] == ["BLENDER_EEVEE", "CPU", False, ""]
    for name, presses in result["pressed"].items():
        for res, lines in presses:
            assert res == ["FINISHED"], (name, lines)
    bake_lines = result["pressed"]["bake_parameters"][0][1]
    assert "not saved" in bake_lines and "choose a Folder" in bake_lines
    assert {"params.json", "material.mtlx"} <= set(result["baked"])
    preview_lines = result["pressed"]["preview_neural"][0][1]
    assert "Turned on Open Shading Language" in preview_lines and "Render Engine to Cycles" in preview_lines
    assert result["end"] == ["BLENDER_EEVEE", "CPU", True]  # only the OSL option changed
