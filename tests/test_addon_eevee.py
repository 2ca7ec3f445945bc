"""The add-on with EEVEE as the render engine: Uplift, Bake, Export, Generate and Preview pressed on
Blender's default cube, each result rendered with EEVEE (Mesa's software OpenGL where there is no GPU)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from support.blender_child import eevee_failure
from support.extension import script
from torch_models.render.flip import flip_map
from torch_models.render.tonemap import agx
from .test_addon_extension import extension_zip  # noqa: F401  (session fixture)
from .test_generator_generate import checkpoint  # noqa: F401  (tiny trained generator, module fixture)

WIDTH, HEIGHT = 64, 36  # the default camera's 16:9 frame

PRESS = r'''
bpy.ops.wm.read_factory_settings(use_empty=False)  # the default cube, camera and light; EEVEE
addon_utils.enable(MODULE, default_set=True)
scene = bpy.context.scene
bpy.context.view_layer.objects.active = cube = bpy.data.objects["Cube"]
scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
scene.render.resolution_percentage = 100
scene.eevee.taa_render_samples = 4
renders, pressed, engines = {}, {}, []

def eevee(tag):
    """The camera's view rendered with the scene's engine (EEVEE), top row first."""
    engines.append(scene.render.engine)
    renders[tag] = render_exr(Path(TMP) / f"{tag}.exr")[::-1].tolist()

eevee("factory")
scene.richmat.enhancement_type, scene.richmat.seed = "2", 3
pressed["uplift"] = press("uplift_material")
eevee("uplift")
scene.richmat.output_dir = TMP + "/baked"
pressed["bake"] = press("bake_parameters")
eevee("bake")
pressed["export"] = press("export_materialx", directory=TMP + "/mtlx")
bpy.context.preferences.addons[MODULE].preferences.generator_dir = CHECKPOINT
scene.richmat.prompt, scene.richmat.generate_steps = "red paint with light dust", 2
pressed["generate"] = press("generate_material")
eevee("generate")
pressed["preview"] = press("preview_neural")
eevee("preview")
import gpu
print("RESULT " + json.dumps(dict(
    renders=renders, pressed=pressed, engines=engines, renderer=gpu.platform.renderer_get(),
    material=cube.active_material.name, exported=sorted(p.name for p in Path(TMP, "mtlx").glob("*/*")))))
'''


@pytest.fixture
def eevee() -> None:
    reason = eevee_failure()
    if reason:
        pytest.skip(reason)


def test_every_button_renders_in_eevee(eevee, blender_run, extension_zip: Path, checkpoint: Path,  # noqa: F811
                                       tmp_path: Path):
    """Each button's material compiles and renders in EEVEE; Bake keeps what Uplift drew, Generate assigns
    a material of its own, and Preview shows EEVEE the baked enhanced material's native nodes, as it says."""
    result = blender_run(script(f"TMP = {str(tmp_path)!r}\nCHECKPOINT = {str(checkpoint)!r}\n"
                                f"WIDTH, HEIGHT = {WIDTH}, {HEIGHT}\n" + PRESS, extension_zip), timeout=600)
    for name, (res, lines) in result["pressed"].items():
        assert res == ["FINISHED"], (name, lines)
    assert set(result["engines"]) == {"BLENDER_EEVEE"}  # no button switched the engine
    assert {"material.mtlx", "params.json"} <= set(result["exported"])
    renders = {tag: np.asarray(rgb, np.float32) for tag, rgb in result["renders"].items()}
    for tag, rgb in renders.items():
        assert np.isfinite(rgb).all(), tag
    # The cube: where the factory render is not the world's uniform grey (its corner).
    factory = renders["factory"]
    cube = np.abs(factory - factory[0, 0]).max(-1) > 0.01
    assert 0.05 < cube.mean() < 0.5

    def flip_on_cube(a: str, b: str) -> float:
        return float(flip_map(agx(renders[a]), agx(renders[b]))[0][cube].mean())

    assert flip_on_cube("factory", "uplift") > 0.03  # Type 2's coat changes the look
    assert flip_on_cube("uplift", "bake") < 0.01  # the baked maps draw the same material
    assert flip_on_cube("bake", "generate") > 0.03  # Generate assigned its own material
    assert flip_on_cube("generate", "preview") < 0.005  # EEVEE shows the enhanced material's nodes, as Preview says:
    preview_lines = result["pressed"]["preview"][1]
    assert "EEVEE the baked enhanced material's native nodes" in preview_lines
    assert "Render Engine to Cycles" in preview_lines
