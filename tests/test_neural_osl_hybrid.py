"""The neural preview shader for the hybrid decoder kind: chosen by the weights' own tensor names,
compiled by Cycles' OSL, its lobes Cycles' own closures, in agreement with the torch renderer of the
same closure form (``closure_form.ClosureForm``) under the probe and under a sun lamp."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from richmat_addon.core.colour import LUMINANCE
from richmat_addon.core.neural_osl import neural_osl_source
from richmat_addon.core.tensor_file import read_safetensors

from .test_addon_preview import cycles_ball, torch_ball
from .test_hybrid_decoder import tiny_hybrid, tiny_unit_hybrid  # noqa: F401  (module fixtures: 40-step hybrid runs)

LATENT = [0.3, -0.5, 0.2, 0.7, -0.1, 0.4]
BASE = [0.5, 0.3, 0.2]


def closure_form(folder: Path):
    """The weights' model with the hybrid's gates held constant over wo, as the shader's closures are."""
    import dataclasses

    from torch_models.neural.hybrid.closure_form import ClosureForm
    from torch_models.neural.trained import load

    model = load(folder)
    return dataclasses.replace(model, decoder=ClosureForm(model.decoder))


def agree(cycles: np.ndarray, ref, tolerance: float = 0.04, floor: float = 0.05) -> None:
    """Median and mean luminance over the ball agree within ``tolerance`` (relative). The mean leaves out
    the brightest 1 % of pixels: a near-mirror lobe's pinpoint highlight under a lamp is too rare a hit
    for either renderer to estimate at test sample counts."""
    ball = (cycles[..., 3] > 0.99) & (ref.alpha > 0.99)
    luminance = np.asarray(LUMINANCE)
    c, t = cycles[..., :3][ball] @ luminance, ref.rgb[ball] @ luminance
    assert ball.sum() > 200 and np.isfinite(c).all() and t.mean() > floor, (ball.sum(), t.mean())
    assert abs(np.median(c) / np.median(t) - 1) < tolerance, (np.median(c), np.median(t))
    c_trim, t_trim = c[c <= np.quantile(c, 0.99)].mean(), t[t <= np.quantile(t, 0.99)].mean()
    assert abs(c_trim / t_trim - 1) < tolerance, (c_trim, t_trim)


def test_the_tensor_names_choose_the_hybrid_shader(tiny_hybrid: Path) -> None:  # noqa: F811
    tensors = read_safetensors(tiny_hybrid / "weights.safetensors")
    src = neural_osl_source(tensors)
    # 3 lobes: the head maps [z, cos, sin, Schlick] to 5 K + 7 outputs, the gates [z, wi, wo, h, wi.h] to 3 (K + 1)
    assert "void head_mlp(float x[9], output float y[22])" in src
    assert "void gates_mlp(float x[16], output float y[12])" in src
    assert "sampler_mlp" not in src and "decoder_mlp" not in src and src.count("float W") == 3 + 3
    assert float(re.search(r"#define ALPHA_FLOOR (\S+)", src).group(1)) == pytest.approx(0.002)
    assert "#define T_SLOT 19\n" in src  # slots: 3 GGX lobes, diffuse, T, absorbed after 4 K + 3 outputs
    assert f"{float(tensors['decoder.head.4.weight'][0, 0]):.9g}" in src
    # Cycles lights the lobes itself: closures, no emission and no world probe in the shader
    assert "generalized_schlick_bsdf(" in src and "emission()" not in src and "probe" not in src
    with pytest.raises(ValueError, match="hybrid decoder layout"):
        neural_osl_source({k: v for k, v in tensors.items() if not k.startswith("decoder.gates.4")})


def test_closure_form_holds_each_gate_at_its_mean_over_the_lobe(tiny_hybrid: Path) -> None:  # noqa: F811
    """The closure form's gates depend on (latent, wi) only; its lobes and T are the decoder's; random draws
    converge to the quadrature's mean; a gate that is constant over wo is left exactly as it was."""
    import torch

    from torch_models.neural.hybrid.closure_form import stratified

    form = closure_form(tiny_hybrid).decoder
    decoder = form.decoder
    z = torch.tensor([LATENT] * 4)
    wi = torch.nn.functional.normalize(torch.tensor([[0.3, 0.1, 0.9], [0.0, 0.0, 1.0], [0.6, -0.2, 0.5],
                                                     [0.1, 0.7, 0.3]]), dim=-1)
    wo = torch.nn.functional.normalize(torch.tensor([[-0.2, 0.1, 0.9]] * 4), dim=-1)
    gates = form.gates_at(z, wi, stratified(16))
    assert gates.shape == (4, decoder.lobes + 1, 3) and ((gates > 0) & (gates < 1)).all()
    drawn = torch.stack([form.gates_at(z, wi) for _ in range(200)]).mean(0)  # 400 random draws per lobe
    assert torch.allclose(drawn, gates, atol=0.01), (drawn - gates).abs().max()
    f, t, _ = form(z, wi, wo)
    assert torch.allclose(t, decoder(z, wi, wo)[1])
    assert f.shape == (4, 3) and (f >= 0).all()
    flat = closure_form(tiny_hybrid).decoder  # gates that ignore the directions: the closure form is the decoder
    with torch.no_grad():
        flat.decoder.gates[-1].weight.zero_()
    assert torch.allclose(flat(z, wi, wo)[0], flat.decoder(z, wi, wo)[0], rtol=1e-5, atol=1e-7)


def test_cycles_closures_agree_with_the_torch_closure_form_under_the_probe(
        tiny_hybrid: Path, blender_run, tmp_path: Path) -> None:  # noqa: F811
    """Same networks, latent, probe and ball: Cycles' closures (lit by Cycles' world sampling) against the
    torch renderer of the closure form, within 4 % in mean and median luminance."""
    ref = torch_ball(closure_form(tiny_hybrid), LATENT, BASE, 1.0, 32, 256)
    agree(cycles_ball(blender_run, tiny_hybrid, LATENT, BASE, 32, 128, tmp_path), ref)


SHIPPED = Path(__file__).resolve().parents[1] / "torch_models" / "neural" / "weights"
VIEW_GATED = Path(__file__).resolve().parent / "data" / "view_gated_decoder"  # a trained view-gated hybrid (its README)
# a Type 2 metal (support/agreement_cases.py, seed 0, type2_metal_1): its base and each decoder's encoder latent
METAL_BASE = [0.6001, 0.5731, 0.3761]
METAL_LATENT = {SHIPPED: [0.2547, -0.4069, -0.6685, -0.3168, 0.1747, -0.318],
                VIEW_GATED: [0.3035, -0.1658, -0.3034, 0.1358, 0.2975, -0.3551]}


def test_view_gates_are_evaluated_once_at_wi() -> None:
    """The gate network's input width picks how the shader gets its gates: a view-gated decoder's gates read
    the head's 9 inputs and are evaluated once (no draws), and its torch closure form is the decoder itself."""
    import torch

    src = neural_osl_source(read_safetensors(VIEW_GATED / "weights.safetensors"))
    assert "void gates_mlp(float x[9], output float y[15])" in src and "view_gates(z, wi, g);" in src
    assert "mean_gates" not in src and "gate_samples" not in src and "hashnoise" not in src
    shipped = neural_osl_source(read_safetensors(SHIPPED / "weights.safetensors"))
    assert "void gates_mlp(float x[16], output float y[15])" in shipped and "view_gates" not in shipped
    assert "mean_gates(z, s, wi, P, max(gate_samples, 1), g);" in shipped
    model = closure_form(VIEW_GATED)
    z = torch.tensor([METAL_LATENT[VIEW_GATED]] * 3)
    wi = torch.nn.functional.normalize(torch.tensor([[0.3, 0.1, 0.9], [0.6, -0.2, 0.5], [0.1, 0.7, 0.3]]), dim=-1)
    wo = torch.nn.functional.normalize(torch.tensor([[-0.2, 0.1, 0.9], [-0.5, 0.3, 0.6], [0.0, -0.6, 0.4]]), dim=-1)
    with torch.no_grad():
        assert torch.equal(model.decoder(z, wi, wo)[0], model.decoder.decoder(z, wi, wo)[0])


# mean FLIP over the ball between the two renders (AgX): at the seeds and counts below they differ by
# 0.005-0.007 under the sun and 0.022 under the probe; the view-gated shader with its gates read at normal
# incidence whatever the view reads 0.046 and 0.056, though its luminance stays within 1.5 %
BALL_FLIP = {"sun": 0.02, "probe": 0.035}


@pytest.mark.parametrize("weights, lit_by", [(SHIPPED, "sun"), (VIEW_GATED, "sun"), (VIEW_GATED, "probe")],
                         ids=["shipped-sun", "view_gates-sun", "view_gates-probe"])
def test_cycles_closures_of_a_metal_agree_with_torch(weights: Path, lit_by: str, blender_run, tmp_path: Path) -> None:
    """A clearcoat metal's latent, under one sun lamp in a black world (where the emission preview, which saw
    the world only, rendered black) or under the probe: Cycles' closures agree with the torch renderer of the
    decoder's closure form within 4 % in mean and median luminance, and pixel by pixel within ``BALL_FLIP``.
    For the shipped decoder that form holds each gate at its lobe mean; for the view-gated one it is the
    decoder exactly."""
    from torch_models.render.ball import Sun
    from torch_models.render.flip import flip_map
    from torch_models.render.tonemap import agx

    sun = Sun((0.5773, -0.5773, 0.5773), 3.0) if lit_by == "sun" else None
    spp = (64, 64) if sun else (256, 128)  # torch, Cycles
    latent = METAL_LATENT[weights]
    ref = torch_ball(closure_form(weights), latent, METAL_BASE, 1.0, 32, spp[0], sun=sun)
    cycles = cycles_ball(blender_run, weights, latent, METAL_BASE, 32, spp[1], tmp_path, sun=sun)
    agree(cycles, ref, floor=0.02 if sun else 0.05)
    ball = (cycles[..., 3] > 0.99) & (ref.alpha > 0.99)
    flip = flip_map(agx(np.asarray(ref.rgb)), agx(cycles[..., :3]))[0][ball].mean()
    assert flip < BALL_FLIP[lit_by], flip


# the shipped decoder: 94 % of the energy in one GGX lobe of alpha 0.99, whose albedo E is 0.31 at normal incidence
ROUGH_LATENT = [0.5476, -0.0788, -0.9507, -0.9325, -0.8425, -0.9506]


def test_cycles_closures_of_a_unit_lobe_hybrid_agree_with_torch(blender_run, tmp_path: Path) -> None:
    """The shipped hybrid divides its GGX lobes by their albedo, and the E table travels in its weights.
    At a latent whose lobe is fully rough (alpha ~1, where the division is a factor of 3 at normal
    incidence) and a black base, Cycles' GGX closures agree with torch within 4 %: a shader that
    skipped the division would read less than half of it (0.42 in torch)."""
    assert "#define UNIT_LOBES 1" in neural_osl_source(read_safetensors(SHIPPED / "weights.safetensors"))
    black = [0.0, 0.0, 0.0]
    ref = torch_ball(closure_form(SHIPPED), ROUGH_LATENT, black, 1.0, 32, 256)
    agree(cycles_ball(blender_run, SHIPPED, ROUGH_LATENT, black, 32, 128, tmp_path), ref, floor=0.1)


def sheen_hybrid(folder: Path) -> Path:
    """A weights folder whose hybrid spends nearly all its energy on the sheen slot (roughness ~0.3,
    an orange colour): random networks with the head's last biases set so."""
    import json

    import torch
    from safetensors.torch import save_file

    from torch_models.neural.hybrid.config import HybridConfig
    from torch_models.neural.hybrid.kind import KIND
    from torch_models.neural.networks import Encoder

    torch.manual_seed(0)
    dec = KIND.build_decoder(HybridConfig(unit_lobes=True, sheen=True))
    k = dec.lobes
    with torch.no_grad():
        dec.head[-1].weight.mul_(0.1)
        bias = dec.head[-1].bias
        bias[4 * k + 3:4 * k + 7] = torch.tensor([-0.85, 2.0, 0.0, -2.0])  # roughness sigmoid ~0.3, colour
        bias[4 * k + 7:-1] = -6.0
        bias[4 * k + 7 + k + 1] = 6.0  # the sheen slot
    tensors = {f"encoder.{n}": v for n, v in Encoder().state_dict().items()}
    tensors.update({f"decoder.{n}": v.contiguous() for n, v in dec.state_dict().items()})
    folder.mkdir(parents=True, exist_ok=True)
    save_file(tensors, str(folder / "weights.safetensors"))
    (folder / "state.json").write_text(json.dumps({"step": 0, "config": {"kind": "hybrid", "unit_lobes": True,
                                                                         "sheen": True}}))
    return folder


def test_cycles_sheen_closure_agrees_with_the_torch_closure_form(blender_run, tmp_path: Path) -> None:
    """Nearly all energy in the sheen slot and a black base: Cycles' sheen closure divided by its albedo R
    (the shader reads R from the sheen table) agrees with torch within 4 % in mean and median luminance
    (a shader that left R in would read a small fraction of it at this roughness)."""
    import torch

    folder = sheen_hybrid(tmp_path / "sheen")
    src = neural_osl_source(read_safetensors(folder / "weights.safetensors"))
    assert "#define SHEEN 1\n" in src and "void sheen_ltc(" in src and "sheen(n, s[SHEEN_R])" in src
    model = closure_form(folder)
    lobes = model.decoder.decoder.head_at(torch.tensor([LATENT]), torch.tensor([[0.0, 0.0, 1.0]]))
    assert lobes.weights[0, model.decoder.lobes + 1] > 0.95 and 0.2 < lobes.sheen_roughness.item() < 0.4
    black = [0.0, 0.0, 0.0]
    ref = torch_ball(model, LATENT, black, 1.0, 32, 256)
    agree(cycles_ball(blender_run, folder, LATENT, black, 32, 128, tmp_path), ref)
