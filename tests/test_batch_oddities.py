"""Objaverse's oddities through the farm: each a generated asset (tests/oddity_assets.py) and its stated outcome.

docs/batch.md's table "Objaverse's oddities" names the test that holds each row.
Two runs share the work, since a full tiny run costs about a minute per rendered
asset on a busy 2-core machine:

* ``prepared``: the prepare stage (import, checks, unwrapping, material reading,
  enhancement) of every asset whose outcome is decided there, all in one Blender
  process, then each saved scene looked at frame by frame;
* ``farm``: one tiny farm run (real Blender and torch) over the assets that must be
  rendered end to end (Draco, the skinned and animated column) or refused (a huge
  mesh, a .gltf with a missing buffer, one whose URI leads out of its folder).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from batch import ledger
from richmat_addon.core import material_folder
from richmat_addon.core.colour import srgb_to_linear
from tests import oddity_assets as odd
from support.blender_child import run_blender
from tests.test_batch_render import check_intrinsics, decoder_folder
from tests.test_gltf_io import base_color_image

REPO = Path(__file__).resolve().parents[1]
MAX_TRIANGLES = 5000
HUGE_CELLS = 60  # 7200 triangles: over MAX_TRIANGLES
PREPARE_FRAMES = (0, 1, 7)

INSPECT = """
import json
from pathlib import Path
import bpy
import numpy as np
from batch import blender_job

def world_box(scene):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    points = []
    for obj in scene.objects:
        if obj.type == "MESH":
            evaluated = obj.evaluated_get(depsgraph)
            mesh = evaluated.to_mesh()
            points += [tuple(evaluated.matrix_world @ v.co) for v in mesh.vertices]
            evaluated.to_mesh_clear()
    return [np.min(points, 0).tolist(), np.max(points, 0).tolist()]

results = {}
for name, asset in ASSETS.items():
    work = Path(ROOT) / name
    work.mkdir()
    code = blender_job.main(["prepare", "--asset", asset, "--work", str(work), "--asset-id", name, "--type", "0",
                             "--seed", "0", "--max-texture", "16", "--max-triangles", str(MAX_TRIANGLES)])
    result = {"code": code}
    if code == 0:
        bpy.ops.wm.open_mainfile(filepath=str(work / "scene.blend"), load_ui=False, use_scripts=False)
        scene = bpy.context.scene
        result["types"] = sorted(o.type for o in scene.objects)
        result["render_uv"] = {o.name: next(uv.name for uv in o.data.uv_layers if uv.active_render)
                               for o in scene.objects if o.type == "MESH" and o.data.uv_layers}
        result["boxes"] = {}
        for frame in FRAMES:
            scene.frame_set(frame)
            result["boxes"][frame] = world_box(scene)
    results[name] = result
print("RESULT " + json.dumps(results))
"""


@pytest.fixture(scope="module")
def prepared(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, Any]]:
    """Per asset: the prepare stage's exit code, asset.json or error.json, and its saved scene looked at."""
    root = tmp_path_factory.mktemp("prepared")
    inputs = root / "in"
    assets = {"ktx2_fallback": odd.write_ktx2(inputs, fallback=True),
              "ktx2_only": odd.write_ktx2(inputs, fallback=False),
              "vertex_colours": odd.write_vertex_colours(inputs), "uv_sets": odd.write_uv_sets(inputs),
              "skinned": odd.write_skinned(inputs), "lights_cameras": odd.write_lights_cameras(inputs),
              "huge_quads": odd.write_huge_obj(inputs, HUGE_CELLS), "missing_image": odd.write_missing_image(inputs),
              "alpha_blend": odd.write_alpha_blend(inputs)}
    work = root / "work"
    work.mkdir()
    header = (f"ASSETS = {json.dumps({k: str(v) for k, v in assets.items()})}\nROOT = {str(work)!r}\n"
              f"MAX_TRIANGLES = {MAX_TRIANGLES}\nFRAMES = {PREPARE_FRAMES}\n")
    results = run_blender(header + INSPECT, root, timeout=600)
    for name, result in results.items():
        for record in ("asset.json", "error.json"):
            if (work / name / record).is_file():
                result[record] = json.loads((work / name / record).read_text())
        result["work"] = work / name
    return results


@pytest.fixture(scope="module")
def farm(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """One tiny farm run: the ledger records by source, the output folder, and the fifo an escape points at."""
    root = tmp_path_factory.mktemp("farm")
    inputs, out = root / "in", root / "out"
    odd.write_draco(inputs)
    odd.write_skinned(inputs)
    odd.write_huge(inputs, HUGE_CELLS)
    odd.write_missing_buffer(inputs)
    _, fifo = odd.write_outside_uris(inputs)
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(root / "blender_user"), PYTHONPATH=str(REPO))
    cmd = [sys.executable, str(REPO / "batch" / "render_dataset.py"), "--input", str(inputs), "--output", str(out),
           "--frames", "2", "--resolution", "32", "--samples", "1", "--aov-samples", "1", "--fit-steps", "1",
           "--max-texture", "16", "--max-triangles", str(MAX_TRIANGLES), "--decoder", str(decoder_folder()),
           "--timeout", "400", "--retries", "0"]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=1500)
    assert proc.returncode == 1, proc.stderr[-3000:]  # the refused assets failed, the batch finished
    records = {r["source"]: r for path in (out / "_ledger").glob("*.jsonl") for r in ledger.read(path)}
    return {"records": records, "out": out, "fifo": fifo}


def published(farm: dict[str, Any], source: str) -> Path:
    record = farm["records"][source]
    assert record["status"] == "done", record
    return farm["out"] / record["asset_id"]


def material_record(result: dict[str, Any]) -> dict[str, Any]:
    (material,) = result["asset.json"]["materials"]
    return material


# --- one test per oddity -------------------------------------------------------------------------------

def test_draco_mesh_is_decoded_and_rendered(farm: dict[str, Any]) -> None:
    folder = published(farm, "draco.glb")
    prepared = json.loads((folder / "asset.json").read_text())
    assert prepared["geometry"]["triangles"] == 224  # the 16 x 8 sphere, decoded by Blender's Draco library
    assert prepared["materials"][0]["mean_base_color"] == pytest.approx([0.8, 0.3, 0.1], abs=1e-3)
    check_intrinsics(folder / "passes" / "0000.exr")


def test_ktx2_texture_with_a_png_fallback_uses_the_png(prepared: dict[str, Any]) -> None:
    result = prepared["ktx2_fallback"]
    assert result["code"] == 0
    assert ("KHR_texture_basisu texture 0: Blender cannot read KTX2; used the fallback image images[1] ('png')"
            in result["asset.json"]["notes"])
    expected = srgb_to_linear(base_color_image() / 255.0).mean(axis=(0, 1)) * [0.2, 0.6, 0.9]
    assert material_record(result)["mean_base_color"] == pytest.approx(expected.tolist(), abs=2e-3)


def test_ktx2_texture_without_a_fallback_is_dropped_for_its_factor(prepared: dict[str, Any]) -> None:
    result = prepared["ktx2_only"]
    assert result["code"] == 0  # Blender alone refuses the file: it requires KHR_texture_basisu
    assert ("KHR_texture_basisu texture 0: Blender cannot read KTX2 and the file has no PNG/JPEG fallback: "
            "dropped from pbrMetallicRoughness.baseColorTexture of material 'basis' (its factor is used)"
            in result["asset.json"]["notes"])
    assert material_record(result)["mean_base_color"] == pytest.approx([0.2, 0.6, 0.9], abs=1e-6)


def test_vertex_colours_without_textures_are_baked_into_the_base_colour(prepared: dict[str, Any]) -> None:
    result = prepared["vertex_colours"]
    notes = result["asset.json"]["notes"]
    assert "Mesh_0: no UVs, unwrapped with xatlas" in notes
    assert ("vertex colours (the render colour attribute) of 'DefaultMaterial' baked into its base colour "
            "(16x16 texels)" in notes)
    base = material_folder.read(result["work"] / "materials" / material_record(result)["folder"]).map("base_color")
    assert base.shape == (16, 16)
    # COLOR_0 is the position + 0.5: every channel spans [0, 1] over the cube, 0.5 on average
    assert np.asarray(material_record(result)["mean_base_color"]) == pytest.approx([0.5, 0.5, 0.5], abs=0.05)
    assert base.value.reshape(-1, 3).std(axis=0).min() > 0.1


def test_several_uv_sets_render_with_the_one_the_maps_read(prepared: dict[str, Any]) -> None:
    result = prepared["uv_sets"]
    assert ("'Mesh_0' has 2 UV sets (UVMap, UVMap.001): the maps of 'second_uv' use 'UVMap.001'"
            in result["asset.json"]["notes"])
    assert result["render_uv"] == {"Mesh_0": "UVMap.001"}  # what the enhanced maps are sampled with


def test_skinned_and_animated_mesh_keeps_its_rest_pose_in_every_frame(prepared: dict[str, Any],
                                                                      farm: dict[str, Any]) -> None:
    result = prepared["skinned"]
    notes = result["asset.json"]["notes"]
    assert "1 animation(s) in the file not imported: rendered in the rest pose" in notes
    assert "skinned mesh(es) 'body': rendered in the rest pose" in notes
    boxes = list(result["boxes"].values())
    assert all(box == boxes[0] for box in boxes), result["boxes"]  # nothing moves between frames
    lo, hi = np.array(boxes[0])
    # the straight 0.8 x 2 column, normalised: the file's bent pose and the animation's lift are gone
    assert hi - lo == pytest.approx([0.4, 0.4, 1.0], abs=1e-4) and lo == pytest.approx([-0.2, -0.2, -0.5], abs=1e-4)
    folder = published(farm, "skinned.glb")
    assert json.loads((folder / "manifest.json").read_text())["notes"][:2] == notes[:2]
    for frame in ("0000", "0001"):  # rendered positions stay in the normalised cube
        check_intrinsics(folder / "passes" / f"{frame}.exr")


def test_alpha_blending_rendered_opaque_is_noted(prepared: dict[str, Any]) -> None:
    result = prepared["alpha_blend"]
    assert result["code"] == 0
    record = result["asset.json"]
    note = "'pane' has alpha blending (alpha 0.4): rendered opaque, the enhanced material has no alpha"
    assert note in record["notes"]
    materials = {m["name"]: m for m in record["materials"]}
    assert materials["pane"]["notes"] == [note] and materials["frame"]["notes"] == []  # the opaque one: no note


def test_lights_and_cameras_of_the_asset_are_ignored(prepared: dict[str, Any]) -> None:
    result = prepared["lights_cameras"]
    record = result["asset.json"]
    assert ("2 light(s) and 2 camera(s) in the asset ignored: the dataset's camera orbit and light probe are used"
            in record["notes"])
    assert record["removed"]["lights"] == 2 and record["removed"]["cameras"] == 2
    assert result["types"] == ["EMPTY", "MESH"]  # the normalisation root and the cube
    # the cube hangs under the camera node 5 units along x: removing the camera kept it there
    assert record["normalisation"]["bbox_min"] == pytest.approx([4.5, -0.5, -0.5], abs=1e-5)


def test_huge_polycount_is_refused_with_the_count(prepared: dict[str, Any], farm: dict[str, Any]) -> None:
    expected = f"the meshes have {2 * HUGE_CELLS ** 2} triangles, more than --max-triangles {MAX_TRIANGLES}: refused"
    assert farm["records"]["huge.glb"]["reason"] == "prepare: " + expected  # counted from the JSON, not imported
    assert prepared["huge_quads"]["error.json"]["reason"] == expected  # any format: counted after the import


def test_gltf_with_missing_external_files(prepared: dict[str, Any], farm: dict[str, Any]) -> None:
    buffer = farm["records"]["missing_buffer/missing_buffer.gltf"]
    assert buffer["status"] == "failed" and buffer["attempts"] == 1
    assert buffer["reason"].startswith("prepare: import failed: buffers[0] refers to external file 'gone.bin', "
                                       "which is missing (looked for ")
    image = prepared["missing_image"]
    (note,) = image["asset.json"]["notes"]
    assert note.startswith("images[0] refers to external file 'gone.png', which is missing (looked for ")
    assert note.endswith(": dropped from pbrMetallicRoughness.baseColorTexture of material 'painted' "
                         "(its factor is used)")
    assert material_record(image)["mean_base_color"] == pytest.approx([0.5, 0.5, 0.5], abs=1e-6)


def test_gltf_uri_out_of_its_folder_is_refused_and_nothing_read(farm: dict[str, Any]) -> None:
    record = farm["records"]["escape/escape.gltf"]
    # the URI names a fifo: had anything opened it to read, the asset would have hung until its timeout
    assert record["reason"].startswith("prepare: import failed: images[0] refers to '../outside/paint.png', "
                                       "which is refused: it leads out of the asset's folder")
    assert not record["timed_out"] and farm["fifo"].exists()
