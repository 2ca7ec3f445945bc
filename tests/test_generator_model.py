"""EDM preconditioning, uncertainty-weighted loss, Heun sampler and the multi-view DiT on tiny sizes."""
import json
import math
from dataclasses import replace

import pytest
import torch
from safetensors.torch import save_file

from richmat_addon.core.enhancement_types import TYPES
from torch_models.generator import edm
from torch_models.generator.dit import CONDITION_CHANNELS, LATENT_CHANNELS, Conditions, DitConfig, LatentGenerator
from torch_models.generator.generate import load_generator
from torch_models.generator.train import GeneratorTrainConfig
from torch_models.generator.views import PBR_CHANNELS, PRIOR_CHANNELS

torch.set_num_threads(1)
TINY = DitConfig(size=8, patch=4, dim=32, depth=2, heads=2, text_dim=12)


def _conditions(b: int = 1, v: int = 2, seed: int = 0) -> Conditions:
    g = torch.Generator().manual_seed(seed)
    views = torch.rand(b, v, CONDITION_CHANNELS, TINY.size, TINY.size, generator=g)
    views[:, :, -1] = (views[:, :, -1] > 0.2).float()  # coverage
    views[:, :, PRIOR_CHANNELS] *= views[:, :, -1:]  # the prior, like every map, is 0 on the background
    unknown_prior = torch.rand(b, v, LATENT_CHANNELS, TINY.size, TINY.size, generator=g) * views[:, :, -1:]
    return Conditions(views, torch.randn(b, TINY.text_dim, generator=g), torch.tensor([1] * b), unknown_prior)


def test_preconditioning_values_at_sigma_data():
    s = edm.scalings(torch.tensor(0.5))
    assert math.isclose(float(s.c_skip), 0.5, rel_tol=1e-6)
    assert math.isclose(float(s.c_out), 0.25 / math.sqrt(0.5), rel_tol=1e-6)
    assert math.isclose(float(s.c_in), 1 / math.sqrt(0.5), rel_tol=1e-6)
    assert math.isclose(float(s.c_noise), 0.25 * math.log(0.5), rel_tol=1e-6)


def test_preconditioning_gives_unit_variance_input_and_target():
    """The point of EDM scalings: c_in x and the effective target (y - c_skip x) / c_out are unit variance."""
    g = torch.Generator().manual_seed(0)
    for sigma in (0.01, 0.3, 5.0):
        y = edm.SIGMA_DATA * torch.randn(200_000, generator=g)
        x = y + sigma * torch.randn(200_000, generator=g)
        s = edm.scalings(torch.tensor(sigma))
        assert abs(float((s.c_in * x).std()) - 1) < 0.01
        assert abs(float(((y - s.c_skip * x) / s.c_out).std()) - 1) < 0.01
        assert math.isclose(float(edm.loss_weight(torch.tensor(sigma))), float(s.c_out) ** -2, rel_tol=1e-5)


def test_training_noise_levels_are_lognormal():
    ln = edm.sample_sigma(50_000, torch.Generator().manual_seed(1)).log()
    assert abs(float(ln.mean()) - edm.P_MEAN) < 0.03 and abs(float(ln.std()) - edm.P_STD) < 0.03


def test_uncertainty_weighting_optimum_is_the_log_of_the_weighted_error():
    """d/du (L e^-u + u) = 0 at u = ln L: the learned log-variance tracks each level's error."""
    x0 = torch.zeros(1, 4)
    pred = torch.full((1, 4), 0.3)
    sigma = torch.tensor([0.5])
    err = float(edm.loss_weight(sigma)) * 0.09
    values = [float(edm.weighted_loss(x0, pred, sigma, torch.tensor([u]), torch.ones(1, 4)))
              for u in (math.log(err) - 0.5, math.log(err), math.log(err) + 0.5)]
    assert values[1] < values[0] and values[1] < values[2]
    assert math.isclose(values[1], 1 + math.log(err), rel_tol=1e-5)


def test_mask_ignores_background():
    x0, pred = torch.zeros(1, 2, 2), torch.tensor([[[0.0, 0.0], [5.0, 5.0]]])
    mask = torch.tensor([[[1.0, 1.0], [0.0, 0.0]]])
    assert float(edm.weighted_loss(x0, pred, torch.ones(1), torch.zeros(1), mask)) == 0.0


def test_heun_sampler_with_the_exact_denoiser_reproduces_the_data_distribution():
    """For data ~ N(0, sigma_data^2) the ideal denoiser is x sigma_data^2 / (sigma_data^2 + sigma^2)."""
    def ideal(x, sigma):
        s = sigma.reshape(-1, 1)
        return x * edm.SIGMA_DATA ** 2 / (edm.SIGMA_DATA ** 2 + s ** 2)
    noise = torch.randn(4, 20_000, generator=torch.Generator().manual_seed(2))
    errors = [abs(float(edm.heun_sample(ideal, noise, steps=k).std()) - edm.SIGMA_DATA) for k in (18, 40)]
    assert errors[1] < 0.01 and errors[1] < errors[0] < 0.05  # 2nd-order solver: converges with steps
    sigmas = edm.karras_sigmas(18)
    assert math.isclose(float(sigmas[0]), edm.SIGMA_MAX, rel_tol=1e-5) and float(sigmas[-1]) == 0.0
    assert math.isclose(float(sigmas[-2]), edm.SIGMA_MIN, rel_tol=1e-4)
    assert bool((sigmas[1:] < sigmas[:-1]).all())


def test_model_shapes_and_background_is_zero():
    model = LatentGenerator(TINY)
    cond = _conditions(b=2, v=3)
    x = torch.randn(2, 3, LATENT_CHANNELS, TINY.size, TINY.size)
    out = model.denoise(x, torch.tensor([0.1, 2.0]), cond)
    assert out.shape == x.shape
    assert bool((out[cond.views[:, :, -1:].expand_as(out) == 0] == 0).all())
    # small sigma: c_skip -> 1, c_out -> 0, so D(x) ~ x on the object
    tiny = model.denoise(x, torch.full((2,), 1e-4), cond)
    covered = cond.views[:, :, -1:].expand_as(x) > 0
    assert torch.allclose(tiny[covered], x[covered], atol=1e-3)


def test_prompt_dropout_and_unconditional_input():
    model = LatentGenerator(TINY)
    assert model.null_type == len(TYPES) and model.net.type_embed.num_embeddings == len(TYPES) + 1
    cond = _conditions(b=2)
    dropped = cond.drop(torch.tensor([True, False]), model.null_type)
    assert torch.equal(dropped.text[0], cond.text[0]) and float(dropped.text[1].abs().sum()) == 0.0
    assert dropped.type.tolist() == [1, model.null_type]
    assert cond.unconditional(model.null_type).type.tolist() == [model.null_type, model.null_type]


def test_a_checkpoint_keeps_its_type_count_and_refuses_types_it_never_saw(tmp_path):
    """The unconditional token is one past the checkpoint's types, whatever today's table holds: a
    checkpoint of two types (its state.json silent on the count, as before ``DitConfig.types``)
    loads with two, and Type 2, its unconditional token, is refused as a prompt's type."""
    trained = LatentGenerator(replace(TINY, types=2))
    save_file(trained.state_dict(), str(tmp_path / "weights.safetensors"))
    config = GeneratorTrainConfig(model=TINY).to_dict()
    del config["model"]["types"]
    (tmp_path / "state.json").write_text(json.dumps({"config": config}))
    model, cfg = load_generator(tmp_path)
    assert cfg.model.types == 2 and model.null_type == 2
    cond = _conditions(b=2)
    assert model.sample(cond, steps=1, seed=0).shape == (2, 2, LATENT_CHANNELS, TINY.size, TINY.size)
    cond.type = torch.tensor([1, 2])
    with pytest.raises(ValueError, match="trained on enhancement types 0-1"):
        model.sample(cond, steps=1, seed=0)


def test_dropping_the_pbr_maps_swaps_in_the_prior_made_without_them():
    cond = _conditions(b=2)
    dropped = cond.drop_pbr(torch.tensor([True, False]))
    assert torch.equal(dropped.views[0], cond.views[0])
    assert float(dropped.views[1][:, PBR_CHANNELS].abs().max()) == 0.0
    assert torch.equal(dropped.prior[1], cond.unknown_prior[1])
    keep = [c for c in range(CONDITION_CHANNELS) if c not in range(9, 18)]
    assert torch.equal(dropped.views[1][:, keep], cond.views[1][:, keep])


def test_the_model_learns_the_residual_over_the_prior():
    """A target equal to its prior is a zero residual: the exact loss at sigma -> 0 does not depend
    on the prior's values, and the training loss only sees target - prior."""
    torch.manual_seed(0)
    model = LatentGenerator(TINY)
    cond = _conditions(b=2, v=2, seed=5)
    residual = 0.1 * torch.randn(2, 2, LATENT_CHANNELS, TINY.size, TINY.size,
                                 generator=torch.Generator().manual_seed(6)) * cond.views[:, :, -1:]
    shifted = Conditions(cond.views.clone(), cond.text, cond.type, cond.unknown_prior + 0.3 * cond.views[:, :, -1:])
    shifted.views[:, :, PRIOR_CHANNELS] += 0.3 * cond.views[:, :, -1:]
    loss = lambda target, c: float(model(target, c, torch.Generator().manual_seed(1), drop_prob=0.0,
                                         pbr_drop_prob=0.5).detach())
    same_residual = loss(cond.prior + residual, cond), loss(shifted.prior + residual, shifted)
    other_residual = loss(cond.prior + residual + 0.3 * cond.views[:, :, -1:], cond)
    # the untrained network's output layer is zero, so only the residual target matters
    assert same_residual[0] == pytest.approx(same_residual[1], rel=1e-5)
    assert other_residual > same_residual[0] + 0.1


def test_overfit_two_samples_loss_is_finite_and_falls():
    torch.manual_seed(0)
    model = LatentGenerator(TINY)
    cond = _conditions(b=2, v=2, seed=3)
    x0 = 0.5 * torch.tanh(torch.randn(2, 2, LATENT_CHANNELS, TINY.size, TINY.size,
                                      generator=torch.Generator().manual_seed(4))) * cond.views[:, :, -1:]
    x0 = x0 + cond.prior
    opt = torch.optim.Adam(model.parameters(), lr=2e-3)
    losses = []
    for step in range(120):
        loss = model(x0, cond, torch.Generator().manual_seed(step % 4), drop_prob=0.0)
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    assert all(math.isfinite(v) for v in losses)
    assert sum(losses[-8:]) < 0.7 * sum(losses[:8])


def _perturbed_generator() -> LatentGenerator:
    torch.manual_seed(0)
    model = LatentGenerator(TINY)
    for p in model.parameters():  # a non-trivial network: adaLN-Zero starts as the identity
        p.data.add_(0.05 * torch.randn_like(p))
    return model


def test_sampler_is_deterministic_per_seed_and_cfg_one_is_conditional():
    model = _perturbed_generator()
    cond = _conditions(b=1, v=2)
    a = model.sample(cond, steps=4, seed=7, guidance=1.0)
    assert a.shape == (1, 2, LATENT_CHANNELS, TINY.size, TINY.size) and bool(a.isfinite().all())
    assert torch.equal(a, model.sample(cond, steps=4, seed=7, guidance=1.0))
    assert not torch.allclose(a, model.sample(cond, steps=4, seed=8, guidance=1.0))
    noise = torch.randn(a.shape, generator=torch.Generator().manual_seed(7))
    conditional = edm.heun_sample(lambda x, s: model.denoise(x, s, cond), noise, 4)
    assert torch.allclose(a, conditional, atol=1e-5)
    assert not torch.allclose(a, model.sample(cond, steps=4, seed=7, guidance=3.0), atol=1e-4)


def test_guidance_one_skips_the_unconditional_pass_and_two_extrapolates_past_the_prompted_model():
    calls = []
    cond = lambda x, s: calls.append("cond") or x + 1.0
    uncond = lambda x, s: calls.append("uncond") or x - 1.0
    x, sigma = torch.zeros(3), torch.ones(3)
    assert torch.equal(edm.guided(cond, uncond, 1.0)(x, sigma), x + 1.0) and calls == ["cond"]
    calls.clear()
    assert torch.equal(edm.guided(cond, uncond, 2.0)(x, sigma), x + 3.0) and sorted(calls) == ["cond", "uncond"]


def test_averaged_samples_are_each_objects_mean_over_its_own_draws():
    model = _perturbed_generator()
    cond = _conditions(b=2, v=2)
    avg = model.sample(cond, steps=4, seed=7, guidance=1.0, samples=3)
    assert avg.shape == (2, 2, LATENT_CHANNELS, TINY.size, TINY.size)
    noise = torch.randn((6, *avg.shape[1:]), generator=torch.Generator().manual_seed(7))
    for i in range(2):  # draws 3i..3i+2 belong to object i
        one = Conditions(cond.views[i:i + 1].repeat(3, 1, 1, 1, 1), cond.text[i:i + 1].repeat(3, 1),
                         cond.type[i:i + 1].repeat(3))
        draws = edm.heun_sample(lambda x, s: model.denoise(x, s, one), noise[3 * i:3 * i + 3], 4)
        assert torch.allclose(avg[i], draws.mean(0), atol=1e-5)
        assert draws.std(0).mean() > 10 * (avg[i] - draws.mean(0)).abs().max()
    assert torch.equal(model.sample(cond, steps=4, seed=7, guidance=1.0, samples=1),
                       model.sample(cond, steps=4, seed=7, guidance=1.0))
