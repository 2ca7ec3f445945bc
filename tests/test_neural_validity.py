"""Latent robustness on small sizes: decoding of latents nobody fitted, the furnace and its guard."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import torch

from tests.test_neural_fit import tiny_weights  # noqa: F401  (fixture)
from tests.test_neural_training import constant_decoder
from torch_models.neural import energy, furnace, quadrature, validity
from torch_models.neural.model import NeuralModel
from torch_models.neural.trained import load


def _constant_model(tiny: NeuralModel, albedo: float) -> NeuralModel:
    """The tiny model with a decoder whose f_neu albedo is ``albedo`` at every latent and angle."""
    return NeuralModel(tiny.encoder, constant_decoder(tiny.decoder.width, tiny.decoder.depth, albedo),
                       tiny.sampler, "constant", tiny.alpha_floor, tiny.relative_weight, tiny.t_weight)


def test_furnace_estimates_a_known_albedo(tiny_weights: Path) -> None:  # noqa: F811
    model = _constant_model(load(tiny_weights), 0.8)
    check = furnace.furnace(model, torch.rand(4, 6) * 2 - 1, n=4096)
    err = (check.albedos - 0.8).abs()
    assert (err < 4 * check.std_errors + 1e-3).all(), check.albedos
    # this f cos jumps to 0 at the horizon, which cuts through quadrature cells: 2.5 % (real f cos fades to 0 there)
    assert ((check.quadrature - 0.8).abs() < 0.025 * 0.8).all(), check.quadrature
    assert not check.failing.any()
    assert check.transmissions.max() < 1e-6  # T ~ sigmoid(-20)


def test_furnace_flags_and_repairs_energy_gain(tiny_weights: Path) -> None:  # noqa: F811
    model = _constant_model(load(tiny_weights), 1.5)
    z = torch.rand(6, 6) * 2 - 1
    check = furnace.furnace(model, z, n=2048)
    assert check.failing.all()
    scale = check.energy_scale()
    assert ((scale > 0.6) & (scale <= 1 / 1.5)).all()  # just enough to bring 1.5 to 1
    assert not furnace.furnace(model, z, n=2048, seed=9, energy_scale=scale).failing.any()
    guarded = energy.guard(model, z)
    assert (guarded <= 1 / 1.5).all() and not furnace.furnace(model, z, n=2048, seed=11, energy_scale=guarded).failing.any()
    # repaired to the point estimate and checked again: no darker than one repair with the error bar
    assert (guarded >= scale).all() and float(guarded.min()) > 1 / 1.5 - 0.02, guarded


def test_half_vector_grid_resolves_a_near_mirror_lobe() -> None:
    # A GGX distribution integrates to 1 over projected half vectors; alpha 1e-3 is a
    # 0.06 degree lobe that a uniform grid of the same size would miss entirely.
    h, d_omega = quadrature.half_vector_grid()
    cos = h[:, 2].double()
    for alpha in (1e-3, 1e-2, 0.3, 1.0):
        a2 = alpha * alpha
        ggx = a2 / (math.pi * (cos * cos * (a2 - 1) + 1) ** 2)
        assert float((ggx * cos * d_omega.double()).sum()) == pytest.approx(1.0, abs=0.025), alpha


def test_box_and_perturbed_latents_decode_finite_non_negative_and_guarded(tiny_weights: Path) -> None:  # noqa: F811
    model = load(tiny_weights)
    box = validity.enlarged(validity.training_latent_box(model, n=400), 1.1)
    gen = torch.Generator().manual_seed(0)
    lo, hi = box
    uniform = lo + (hi - lo) * torch.rand(48, 6, generator=gen)
    fitted = model.encoder(torch.from_numpy(validity.parameter_vectors(16, np.random.default_rng(2))))
    perturbed = fitted + 0.05 * (2 * torch.rand(fitted.shape, generator=gen) - 1)
    for z in (uniform, perturbed, torch.full((2, 6), 1e3), torch.full((2, 6), -1e3)):
        raw = validity.check_latents(model, z.detach(), pairs=64)
        assert raw.finite.all() and raw.non_negative.all()
        guarded = validity.check_latents(model, z.detach(), pairs=64, seed=3,
                                         energy_scale=energy.guard(model, z.detach()))
        assert guarded.valid.all()


def test_enlarged_box_grows_each_side_by_the_factor() -> None:
    lo, hi = validity.enlarged((torch.tensor([0.0, -1.0]), torch.tensor([1.0, 1.0])), 1.1)
    assert torch.allclose(hi - lo, torch.tensor([1.1, 2.2])) and math.isclose(float(lo[0]), -0.05, abs_tol=1e-6)
