"""The neural preview shader: the decoder in OSL against the torch renderer, and the operator."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from richmat_addon.core.neural_osl import neural_osl_source
from richmat_addon.core.tensor_file import read_safetensors

from support.extension import script
from .test_addon_extension import extension_zip  # noqa: F401  (session fixture)

REPO = Path(__file__).resolve().parents[1]
SHIPPED_WEIGHTS = REPO / "torch_models" / "neural" / "weights"
BASELINE_WEIGHTS = SHIPPED_WEIGHTS / "mlp"  # the paper's MLP: its shader integrates the lobe from the probe
PROBE = REPO / "torch_models" / "data" / "studio_small_03_512.hdr"


@pytest.fixture(scope="module")
def untrained_model(tmp_path_factory: pytest.TempPathFactory):
    """Seeded freshly initialised MLP networks saved as a run folder: any weights test the shader's arithmetic."""
    import torch
    from safetensors.torch import save_file

    from torch_models.neural.mlp.networks import Decoder, SamplingDecoder
    from torch_models.neural.networks import Encoder
    from torch_models.neural.trained import load

    torch.manual_seed(7)
    folder = tmp_path_factory.mktemp("untrained")
    nets = {"encoder": Encoder(), "decoder": Decoder(64, 4), "sampler": SamplingDecoder()}
    save_file({f"{name}.{k}": v.contiguous() for name, net in nets.items() for k, v in net.state_dict().items()},
              str(folder / "weights.safetensors"))
    (folder / "state.json").write_text(json.dumps({"config": {"width": 64, "depth": 4}}))
    return folder, load(folder)


def test_source_embeds_every_weight_and_the_reader_needs_no_torch(untrained_model):
    folder, model = untrained_model
    tensors = read_safetensors(folder / "weights.safetensors")
    assert np.allclose(tensors["decoder.net.8.weight"], model.decoder.net[8].weight.numpy())
    src = neural_osl_source(tensors)
    assert "shader richmat_neural" in src and "emission()" in src and "diffuse(n)" in src
    assert src.count("float W") == 5 + 3  # decoder and sampling decoder layers
    with pytest.raises(ValueError, match="layout"):
        neural_osl_source({k: v for k, v in tensors.items() if not k.startswith("decoder.net.8")})


def cycles_ball(blender_run, weights: Path, latent: list[float], base: list[float], res: int, spp: int,
                folder: Path, inputs: dict[str, object] | None = None, sun=None) -> np.ndarray:
    """The preview shader on Cycles' preview ball: RGBA (res, res, 4), top row first. Lit by the probe,
    or with a ``render.ball.Sun`` by that sun alone in a black world. ``inputs`` set the shader's
    other inputs by name (the MLP's ``samples``); the MLP's shader reads the probe itself."""
    inputs = dict(inputs or {})
    out = blender_run(f'''
import numpy as np
from pathlib import Path
from support import blender_preview_scene
from richmat_addon.core.neural_osl import neural_osl_source
from richmat_addon.core.tensor_file import read_safetensors
from support.neural_ball import neural_ball, read_exr, set_material
source = neural_osl_source(read_safetensors({str(weights / "weights.safetensors")!r}))
scene, node = neural_ball(source, Path({str(PROBE)!r}), {res}, {spp})
set_material(node, {latent!r}, {base!r})
for name, value in {inputs!r}.items():
    node.inputs[name].default_value = value
if "probe" in node.inputs and {sun is None!r}:
    node.inputs["probe"].default_value = {str(PROBE)!r}
sun = {None if sun is None else (tuple(sun.direction), sun.irradiance)!r}
if sun is not None:
    background = scene.world.node_tree.nodes["Background"]
    for link in list(background.inputs["Color"].links):
        scene.world.node_tree.links.remove(link)
    background.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    blender_preview_scene.add_sun(scene, *sun)
path = Path({str(folder / "cycles.exr")!r})
blender_preview_scene.render_exr(scene, path)
np.save({str(folder / "cycles.npy")!r}, read_exr(path))
''')
    assert out is None
    return np.load(folder / "cycles.npy")


def torch_ball(model, latent: list[float], base: list[float], energy_scale: float, res: int, spp: int, sun=None):
    """The torch renderer's image of the same neural material on the same ball (the probe, or the sun alone)."""
    import torch

    from torch_models.neural.bsdf import NeuralBsdf
    from torch_models.neural.evaluate import BallSetup
    from torch_models.render.ball import render_ball

    setup = BallSetup.default(res, spp, 0)
    bsdf = NeuralBsdf(model, torch.tensor([latent]), torch.tensor([base]), energy_scale)
    with torch.no_grad():
        return render_ball(lambda n: bsdf, setup.env if sun is None else None, setup.scene, spp, 0, sun=sun)


def test_cycles_preview_agrees_with_the_torch_renderer(untrained_model, blender_run, tmp_path: Path):
    """Same networks, latent, probe and ball: the ball's median colour agrees within 4 %."""
    folder, model = untrained_model
    latent = [0.3, -0.5, 0.2, 0.7, -0.1, 0.4]
    base = [0.5, 0.3, 0.2]
    ref = torch_ball(model, latent, base, 1.0, 32, 64)
    cycles = cycles_ball(blender_run, folder, latent, base, 32, 64, tmp_path, {"samples": 8})
    ball = (cycles[..., 3] > 0.99) & (ref.alpha > 0.99)
    assert ball.sum() > 200
    c_med, t_med = np.median(cycles[..., :3][ball], 0), np.median(ref.rgb[ball], 0)
    assert np.isfinite(cycles).all()
    assert np.allclose(c_med, t_med, rtol=0.04), (c_med, t_med)


def test_diffuse_base_reads_t_as_the_torch_renderer_does(blender_run, tmp_path: Path):
    """The MLP decoder's T varies with wo (0.42 at wo = wi, 0.69 averaged, for this latent at normal
    incidence): the base alone (no lobe directions) must match the torch renderer's, which reads T at every
    wo, in mean over the ball within 4 % (reading T at wo = wi was 12 % too bright)."""
    from torch_models.neural.trained import load

    latent = [-0.9966, -0.888, -0.2335, 0.1728, 0.9929, 0.9932]  # the encoder's latent of a Type 4 dielectric
    base = [0.3048, 0.4093, 0.0741]
    ref = torch_ball(load(BASELINE_WEIGHTS), latent, base, 0.0, 32, 256)
    cycles = cycles_ball(blender_run, BASELINE_WEIGHTS, latent, base, 32, 128, tmp_path, {"samples": 0})
    ball = (cycles[..., 3] > 0.99) & (ref.alpha > 0.99)
    c_mean, t_mean = cycles[..., :3][ball].mean(0), ref.rgb[ball].mean(0)
    assert np.allclose(c_mean, t_mean, rtol=0.04), (c_mean, t_mean)


PREVIEW = r'''
def settings():
    return [scene.render.engine, scene.cycles.device, scene.cycles.shading_system]

obj = procedural_asset(TMP, size=16)
scene = bpy.context.scene
scene.render.engine = "CYCLES"  # Cycles as it starts: the CPU, Open Shading Language off
scene.richmat.enhancement_type = "2"
scene.richmat.output_dir = TMP + "/baked"
scene.richmat.fit_steps = 5
for op in ("uplift_material", "bake_parameters", "fit_neural"):
    res, err = run_op(op)
    assert res == {"FINISHED"}, (op, err)
baked_name = obj.active_material.name
out = {}
# A GPU that cannot run OSL: one line saying what to switch, nothing changed.
cycles_prefs = bpy.context.preferences.addons["cycles"].preferences
cycles_prefs.compute_device_type, scene.cycles.device = "CUDA", "GPU"
res, lines = press("preview_neural")
out["cuda"] = dict(result=res, lines=lines, settings=settings(), material=obj.active_material.name)
cycles_prefs.compute_device_type, scene.cycles.device = "NONE", "CPU"
# The CPU with OSL off: the preview turns OSL on and says so.
res, lines = press("preview_neural")
material = obj.active_material
img = render(32, 4)
out["cpu"] = dict(result=res, lines=lines, settings=settings(), name=material.name,
                  nodes=sorted(n.name for n in material.node_tree.nodes),
                  cycles_reads=material.node_tree.nodes["richmat_output"].inputs["Surface"].links[0].from_node.name,
                  finite=bool(np.isfinite(img).all()), mean=float(img.mean()))
# EEVEE (Blender's default engine) with OSL off: OSL on for Cycles, and the engine to switch named.
scene.render.engine, scene.cycles.shading_system = "BLENDER_EEVEE", False
res, lines = press("preview_neural")
out["eevee"] = dict(result=res, lines=lines, settings=settings())
out["baked_name"] = baked_name
print("RESULT " + json.dumps(out))
'''


def test_preview_operator_turns_osl_on_where_it_can_and_names_the_switch_where_it_cannot(
        blender_run, extension_zip: Path, tmp_path: Path):  # noqa: F811
    result = blender_run(script(f"TMP = {str(tmp_path)!r}\n" + PREVIEW, extension_zip))
    cuda, cpu, eevee = result["cuda"], result["cpu"], result["eevee"]
    assert cuda["result"] == ["CANCELLED"] and cuda["settings"] == ["CYCLES", "GPU", False]
    assert "CUDA" in cuda["lines"] and "Device to CPU" in cuda["lines"] and "OptiX" in cuda["lines"]
    assert cuda["material"] == result["baked_name"]  # nothing changed
    assert cpu["result"] == ["FINISHED"], cpu["lines"]
    assert cpu["settings"] == ["CYCLES", "CPU", True]  # OSL on; engine and device as they were
    assert "Turned on Open Shading Language" in cpu["lines"] and "Neural preview" in cpu["lines"]
    assert cpu["name"] == "painted_mat (richmat neural)" and cpu["cycles_reads"] == "richmat_neural_osl"
    assert {"richmat_neural_osl", "tex_latent_0", "tex_latent_1", "normal_map"} <= set(cpu["nodes"])
    assert cpu["finite"] and cpu["mean"] > 0
    assert eevee["result"] == ["FINISHED"], eevee["lines"]
    assert eevee["settings"] == ["BLENDER_EEVEE", "CPU", True]
    assert "Turned on Open Shading Language" in eevee["lines"] and "Render Engine to Cycles" in eevee["lines"]
