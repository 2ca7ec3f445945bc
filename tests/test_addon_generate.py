"""Generate Material in Blender: poll, the backend run on a tiny checkpoint, assignment and preview."""
from __future__ import annotations

from pathlib import Path

from support.extension import script
from .test_addon_extension import extension_zip  # noqa: F401  (session fixture)
from .test_generator_generate import checkpoint  # noqa: F401  (tiny trained generator, module fixture)

GENERATE = r'''
obj = procedural_asset(TMP, size=16)
scene = bpy.context.scene
scene.richmat.output_dir = TMP + "/baked"
scene.richmat.generate_steps = 2
polls = {"empty prompt": bpy.ops.richmat.generate_material.poll()}
scene.richmat.prompt = "red paint with light dust"
polls["ready"] = bpy.ops.richmat.generate_material.poll()
bpy.context.view_layer.objects.active = None
polls["no mesh"] = bpy.ops.richmat.generate_material.poll()
bpy.context.view_layer.objects.active = obj
prefs = bpy.context.preferences.addons[MODULE].preferences
prefs.generator_dir = CHECKPOINT
res, err = run_op("generate_material")
enhanced = obj.active_material
nodes = {n.name: n.image.name for n in enhanced.node_tree.nodes if n.name.startswith("neural_latent")}
neural = Path(enhanced.richmat.neural_dir) if enhanced.richmat.neural_dir else None
record = importlib.import_module(MODULE + ".core.neural_folder").read(neural).record if neural else {}
pixels = []
for name in sorted(nodes):
    image = enhanced.node_tree.nodes[name].image
    pixels.append(np.array(image.pixels[:]).reshape(image.size[1], image.size[0], 4)[..., :3].tolist())
preview_res, preview_err = run_op("preview_neural")
print("RESULT " + json.dumps(dict(
    polls=polls, res=list(res), err=err, type=enhanced.richmat.type, bake_dir=enhanced.richmat.bake_dir,
    nodes=nodes, record=record, pixels=pixels, preview=[list(preview_res), preview_err],
    preview_material=obj.active_material.name,
    preview_script="richmat_neural_osl" in obj.active_material.node_tree.nodes)))
'''


def run_generate(blender_run, zip_path: Path, tmp_path: Path, checkpoint_dir: Path) -> dict:
    return blender_run(script(f"TMP = {str(tmp_path)!r}\nCHECKPOINT = {str(checkpoint_dir)!r}\n" + GENERATE,
                              zip_path))


def test_generate_assigns_latents_that_the_neural_preview_renders(blender_run, extension_zip: Path,  # noqa: F811
                                                                    checkpoint: Path, tmp_path: Path):  # noqa: F811
    import numpy as np

    result = run_generate(blender_run, extension_zip, tmp_path, checkpoint)
    assert result["polls"] == {"empty prompt": False, "ready": True, "no mesh": False}
    assert result["res"] == ["FINISHED"], result["err"]
    assert result["type"] == 1  # "light dust": the material was uplifted to the type the prompt names
    record = result["record"]
    assert record["prompt"] == "red paint with light dust" and record["type"] == 1 and record["steps"] == 2
    assert Path(record["checkpoint"]) == checkpoint
    assert record["projection"]["seen"] > 0.5  # the sphere's UV map is covered by the views
    assert result["nodes"] == {"neural_latent_0": "latent_0.exr", "neural_latent_1": "latent_1.exr"}
    latents = np.concatenate([np.asarray(p) for p in result["pixels"]], -1)
    assert latents.shape[-1] == 6 and np.isfinite(latents).all() and np.abs(latents).max() <= 1.0 + 1e-3
    assert latents.reshape(-1, 6).std(0).max() > 0  # not one constant: generated per texel
    assert record["material"] == result["bake_dir"]  # against the baked base colour the preview uses
    assert result["preview"] == [["FINISHED"], None]
    assert result["preview_script"] and result["preview_material"].endswith("(richmat neural)")


def test_a_missing_generator_is_reported_with_the_fix(blender_run, extension_zip: Path,  # noqa: F811
                                                      tmp_path: Path):
    result = run_generate(blender_run, extension_zip, tmp_path, tmp_path / "none")
    assert result["res"] == ["CANCELLED"]
    assert "no trained generator" in result["err"] and "train-generator" in result["err"]
    assert "Traceback" not in result["err"]
    assert result["nodes"] == {} and result["record"] == {}


BARE = r'''
bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16)
obj = bpy.context.active_object
obj.data.materials.append(bpy.data.materials.new("bare"))  # a new material: Principled BSDF at 0.8 grey
scene = bpy.context.scene
scene.richmat.output_dir = TMP + "/baked"
scene.richmat.generate_steps = 2
scene.richmat.prompt = PROMPT


class Layout:
    """Stands in for the panel's layout: keeps the labels it is given."""
    labels = []
    def column(self): return self
    def box(self): return self
    def label(self, text="", icon="NONE"): Layout.labels.append(text)
    def prop(self, *args, **kwargs): pass
    def operator(self, *args, **kwargs): pass
    def separator(self): pass


importlib.import_module(MODULE + ".blender.panels").draw_richmat(Layout(), bpy.context)
bpy.context.preferences.addons[MODULE].preferences.generator_dir = CHECKPOINT
res, err = run_op("generate_material")
enhanced = obj.active_material
core = lambda name: importlib.import_module(MODULE + ".core." + name)
baked = core("material_folder").read(Path(enhanced.richmat.bake_dir))
record = core("neural_folder").read(Path(enhanced.richmat.neural_dir)).record if enhanced.richmat.neural_dir else {}
print("RESULT " + json.dumps(dict(
    labels=Layout.labels, res=list(res), err=err, type=enhanced.richmat.type,
    settings=json.loads(enhanced.richmat.record)["settings"],
    base=np.asarray(baked.map("base_color").value).reshape(-1, 3).mean(0).tolist(),
    metalness=float(np.mean(baked.map("metalness").value)), reading=record.get("reading"))))
'''


def test_a_bare_mesh_gets_the_coloured_metal_the_prompt_names_and_the_panel_shows_the_reading(
        blender_run, extension_zip: Path, checkpoint: Path, tmp_path: Path):  # noqa: F811
    import numpy as np

    from richmat_addon.core.base_materials import METALS

    prompt = "brushed gold metal with heavy haze and a glossy clearcoat"
    result = blender_run(script(f"TMP = {str(tmp_path)!r}\nCHECKPOINT = {str(checkpoint)!r}\nPROMPT = {prompt!r}\n"
                                + BARE, extension_zip))
    assert "Type 2 (Clearcoat): heavy haze" in result["labels"]  # before it runs, what the words were read as
    assert any(line.startswith("colour: gold (#") for line in result["labels"])
    assert "material: brushed gold, metalness 1, roughness 0.35" in result["labels"]
    assert result["res"] == ["FINISHED"], result["err"]
    assert result["type"] == 2 and abs(result["settings"]["haze_weight"] - 0.35) < 1e-6  # heavy: the top third's middle
    assert np.allclose(result["base"], METALS["gold"], atol=2e-3) and result["metalness"] == 1.0
    assert result["reading"]["metal"] == "gold"  # the backend read the same words
