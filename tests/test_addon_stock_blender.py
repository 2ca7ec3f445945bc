"""The extension in a Blender whose Python has no torch, as a user's stock Blender: Uplift -> Bake ->
Fit (the numpy encoder) -> Preview -> Export on a sample asset, and Generate saying what it needs.

The child runs the pip bpy module with the venv's site-packages swapped for a copy of it (links)
without torch, and checks that torch does not import there.
"""
from __future__ import annotations

import sysconfig
import zipfile
from pathlib import Path

import numpy as np

from richmat_addon.core import neural_folder
from richmat_addon.core.folder_io import read_exr
from richmat_addon.core.neural_encoder import Encoder
from richmat_addon.core.texel_vectors import read_vectors
from torch_models.neural import trained

from support.extension import script
from .test_addon_extension import extension_zip  # noqa: F401  (session fixture)

TORCH_PACKAGES = ("torch", "functorch")  # torch, torchgen, their dist-info, functorch


def site_without_torch(folder: Path) -> Path:
    """A folder of links to every entry of this venv's site-packages except torch's."""
    folder.mkdir()
    for entry in Path(sysconfig.get_paths()["purelib"]).iterdir():
        if not entry.name.lower().startswith(TORCH_PACKAGES):
            (folder / entry.name).symlink_to(entry)
    return folder


NO_TORCH = r'''
import importlib.util, sys, sysconfig
from pathlib import Path
VENV_SITE = Path(sysconfig.get_paths()["purelib"]).resolve()
sys.path[:] = [p for p in sys.path if not p or Path(p).resolve() != VENV_SITE]
sys.path.append({site!r})
assert importlib.util.find_spec("torch") is None, "torch still imports in the child"
'''

PIPELINE = r'''
bpy.ops.import_scene.gltf(filepath=ASSET)
for image in bpy.data.images:  # a small asset: the pipeline, not the texture size, is tested here
    image.scale(32, 32)
obj = next(o for o in scene.objects if o.type == "MESH")
bpy.context.view_layer.objects.active = obj
scene.richmat.output_dir = OUT + "/baked"
scene.richmat.enhancement_type = "2"
steps = {}
steps["uplift"] = run_op("uplift_material")
steps["bake"] = run_op("bake_parameters")
steps["fit"] = run_op("fit_neural")
enhanced = obj.active_material
neural_dir, bake_dir = enhanced.richmat.neural_dir, enhanced.richmat.bake_dir
latents = sorted(n.image.name for n in enhanced.node_tree.nodes if n.name.startswith("neural_latent"))
scene.richmat.prompt = "red paint"
generate_polls = bpy.ops.richmat.generate_material.poll()
generate = run_op("generate_material")
scene.render.engine, scene.cycles.shading_system = "CYCLES", True  # the neural preview is an OSL shader
steps["preview"] = run_op("preview_neural")
preview = obj.active_material
preview_material = preview.name
obj.scale *= 2.5 / max(obj.dimensions)  # fills the helper's camera view
pixels = render(24, 4)
def cycles_reads():
    return preview.node_tree.nodes["richmat_output"].inputs["Surface"].links[0].from_node.bl_idname
graphs = [cycles_reads()]
scene.cycles.shading_system = False  # OSL off: the add-on's handler must not leave a black material
bpy.context.view_layer.update()
graphs.append(cycles_reads())
fallback = render(24, 4)
steps["export"] = run_op("export_materialx", directory=OUT + "/mtlx")
print("RESULT " + json.dumps(dict(
    steps={k: [sorted(v[0]), v[1]] for k, v in steps.items()}, neural_dir=neural_dir, bake_dir=bake_dir,
    latents=latents, generate_polls=generate_polls, generate=[sorted(generate[0]), generate[1]],
    preview_material=preview_material, finite=bool(np.isfinite(pixels).all()), mean=float(pixels.mean()),
    graphs=graphs, fallback_mean=float(fallback.mean()),
    torch_imported="torch" in sys.modules, torch_found=importlib.util.find_spec("torch") is not None)))
'''


def test_stock_blender_fits_with_the_numpy_encoder_and_previews(shared_assets: Path, blender_run,
                                                                extension_zip: Path, tmp_path: Path):  # noqa: F811
    decoder = {"decoder/weights.safetensors", "decoder/state.json"}
    assert decoder <= set(zipfile.ZipFile(extension_zip).namelist())  # the extension carries what it uses
    asset = shared_assets / "models" / "WaterBottle.glb"
    header = NO_TORCH.format(site=str(site_without_torch(tmp_path / "site")))
    result = blender_run(header + script(f"ASSET = {str(asset)!r}\nOUT = {str(tmp_path)!r}\n" + PIPELINE,
                                         extension_zip), timeout=600)
    assert not result["torch_found"] and not result["torch_imported"]
    for step, (res, err) in result["steps"].items():
        assert res == ["FINISHED"], (step, err)
    assert result["generate_polls"] is False and result["generate"][0] == ["CANCELLED"]
    assert "needs the torch backend" in result["generate"][1] and "make env" in result["generate"][1]
    assert "Traceback" not in result["generate"][1]

    folder = neural_folder.read(Path(result["neural_dir"]))
    assert folder.record["encoder_only"] is True and folder.decoder_sha256 == trained.digest(trained.SHIPPED)
    assert result["latents"] == ["latent_0.exr", "latent_1.exr"]
    vectors = read_vectors(Path(result["bake_dir"]))
    encoder = Encoder.load(trained.SHIPPED)
    expected = vectors.texels(encoder(encoder.floored(vectors.unique)))
    latents = np.concatenate([read_exr(p) for p in folder.latent_paths], -1)
    assert latents.shape == (*vectors.shape, 6)
    np.testing.assert_allclose(latents, expected, rtol=0, atol=1e-3)  # half-float EXRs
    assert result["preview_material"].endswith("(richmat neural)") and result["finite"] and result["mean"] > 0
    # Cycles with OSL runs the decoder; without OSL it renders the baked material's native nodes, not black.
    assert result["graphs"] == ["ShaderNodeScript", "ShaderNodeGroup"]
    # (the neural lobe is lit by the world only, the native graph by the area light too: means differ)
    assert result["fallback_mean"] > 0.001
    mtlx = sorted((tmp_path / "mtlx").glob("*/material.mtlx"))
    assert mtlx and all((m.parent / "params.json").is_file() for m in mtlx)
