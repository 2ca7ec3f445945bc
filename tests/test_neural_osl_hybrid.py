"""The neural preview shader for the hybrid decoder kind: chosen by the weights' own tensor names,
compiled by Cycles' OSL and in agreement with the torch renderer."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from richmat_addon.core.neural_osl import neural_osl_source
from richmat_addon.core.tensor_file import read_safetensors

from .test_addon_preview import cycles_ball, torch_ball
from .test_hybrid_decoder import tiny_hybrid, tiny_unit_hybrid  # noqa: F401  (module fixtures: 40-step hybrid runs)

LATENT = [0.3, -0.5, 0.2, 0.7, -0.1, 0.4]
BASE = [0.5, 0.3, 0.2]


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
    with pytest.raises(ValueError, match="hybrid decoder layout"):
        neural_osl_source({k: v for k, v in tensors.items() if not k.startswith("decoder.gates.4")})


@pytest.mark.parametrize("samples", [0, 8], ids=["base", "base_and_lobe"])
def test_cycles_preview_of_the_hybrid_agrees_with_the_torch_renderer(
        tiny_hybrid: Path, blender_run, tmp_path: Path, samples: int) -> None:  # noqa: F811
    """Same networks, latent, probe and ball. The base alone (no lobe directions) weights Cycles' diffuse
    closure by T(wi): the ball's mean within 2 %. With the lobe's world-lit emission: within 4 %, in mean
    and in median."""
    from torch_models.neural.weights import load

    model = load(tiny_hybrid)
    ref = torch_ball(model, LATENT, BASE, 1.0 if samples else 0.0, 32, 256)
    cycles = cycles_ball(blender_run, tiny_hybrid, LATENT, BASE, samples, 32, 128, tmp_path)
    ball = (cycles[..., 3] > 0.99) & (ref.alpha > 0.99)
    assert ball.sum() > 200 and np.isfinite(cycles).all()
    c_mean, t_mean = cycles[..., :3][ball].mean(0), ref.rgb[ball].mean(0)
    if samples == 0:
        assert np.allclose(c_mean, t_mean, rtol=0.02), (c_mean, t_mean)
    else:
        c_med, t_med = np.median(cycles[..., :3][ball], 0), np.median(ref.rgb[ball], 0)
        assert np.allclose(c_mean, t_mean, rtol=0.04), (c_mean, t_mean)
        assert np.allclose(c_med, t_med, rtol=0.04), (c_med, t_med)


ROUGH_LATENT = [-0.4201, -0.6599, 0.2976, 0.4623, 0.8082, 0.9779]  # the committed hybrid: one alpha ~1 lobe


def test_cycles_preview_of_a_unit_lobe_hybrid_agrees_with_the_torch_renderer(blender_run, tmp_path: Path) -> None:
    """The committed hybrid divides its GGX lobes by their albedo, and the E table travels in its weights.
    At a latent whose lobe is fully rough (alpha ~1, where the division is a factor of 3) and a black
    base, Cycles' lobe emission agrees with torch within 4 %: a shader that skipped the division would
    read a third of it."""
    from torch_models.neural.weights import load

    folder = Path(__file__).resolve().parents[1] / "torch_models" / "neural" / "weights" / "hybrid"
    assert "#define UNIT_LOBES 1" in neural_osl_source(read_safetensors(folder / "weights.safetensors"))
    black = [0.0, 0.0, 0.0]
    ref = torch_ball(load(folder), ROUGH_LATENT, black, 1.0, 32, 256)
    cycles = cycles_ball(blender_run, folder, ROUGH_LATENT, black, 32, 32, 128, tmp_path)
    ball = (cycles[..., 3] > 0.99) & (ref.alpha > 0.99)
    luminance = np.array([0.2126, 0.7152, 0.0722])
    c_mean, t_mean = cycles[..., :3][ball].mean(0) @ luminance, ref.rgb[ball].mean(0) @ luminance
    assert ball.sum() > 200 and t_mean > 0.1 and abs(c_mean / t_mean - 1) < 0.04, (c_mean, t_mean)


def sheen_hybrid(folder: Path) -> Path:
    """A weights folder whose hybrid spends nearly all its energy on the sheen slot (roughness ~0.3,
    an orange colour): random networks with the head's last biases set so."""
    import json

    import torch
    from safetensors.torch import save_file

    from torch_models.neural.hybrid import HybridDecoder
    from torch_models.neural.networks import Encoder

    torch.manual_seed(0)
    dec = HybridDecoder(unit_lobes=True, sheen=True)
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


def test_cycles_preview_of_a_sheen_hybrid_agrees_with_the_torch_renderer(blender_run, tmp_path: Path) -> None:
    """The sheen slot's LTC table travels in the weights; with nearly all energy in the sheen and a black
    base, Cycles' lobe emission agrees with torch within 4 % in mean and median luminance (a shader that
    read the table transposed, or sampled the LTC without its pdf, would not)."""
    import torch

    from torch_models.neural.weights import load

    folder = sheen_hybrid(tmp_path / "sheen")
    src = neural_osl_source(read_safetensors(folder / "weights.safetensors"))
    assert "#define SHEEN 1\n" in src and "void sheen_ltc(" in src
    model = load(folder)
    lobes = model.decoder.head_at(torch.tensor([LATENT]), torch.tensor([[0.0, 0.0, 1.0]]))
    assert lobes.weights[0, model.decoder.lobes + 1] > 0.95 and 0.2 < lobes.sheen_roughness.item() < 0.4
    black = [0.0, 0.0, 0.0]
    ref = torch_ball(model, LATENT, black, 1.0, 32, 256)
    cycles = cycles_ball(blender_run, folder, LATENT, black, 32, 32, 128, tmp_path)
    ball = (cycles[..., 3] > 0.99) & (ref.alpha > 0.99)
    luminance = np.array([0.2126, 0.7152, 0.0722])
    c, t = cycles[..., :3][ball] @ luminance, ref.rgb[ball] @ luminance
    assert ball.sum() > 200 and t.mean() > 0.05 and np.isfinite(c).all()
    assert abs(c.mean() / t.mean() - 1) < 0.04 and abs(np.median(c) / np.median(t) - 1) < 0.04, (c.mean(), t.mean())
