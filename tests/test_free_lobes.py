"""The hybrid's lobe form with free parameters per material (``free_lobes``): what a decoder with
these lobes should not beat."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from support.agreement_cases import cases
from torch_models.neural import trained
from torch_models.neural.fit.latents import deterministic, fit_latents, fitting_pool, held_out_loss
from torch_models.neural.hybrid import free_lobes
from torch_models.neural.hybrid.closure_form import ClosureForm
from torch_models.neural.model import NeuralModel


@pytest.fixture(scope="module")
def model() -> NeuralModel:
    return trained.load(trained.SHIPPED)


def test_the_free_form_starts_at_the_decoders_closure_form(model: NeuralModel) -> None:
    """Started from latents, it draws what the decoder's closure form draws, up to the linear
    fit of the head and gates over the view angle."""
    free = free_lobes.free_model(model)
    metals = [c for c in cases(0, 2, 0) if "metal" in c.name]
    z = model.encoder(fitting_pool(model, np.stack([c.vector() for c in metals]))).detach()
    params = free_lobes.start_from(model, free, z)
    gen = torch.Generator().manual_seed(0)
    wi, wo = (torch.nn.functional.normalize(torch.rand(256, 3, generator=gen) * torch.tensor([2.0, 2.0, 1.0])
                                            - torch.tensor([1.0, 1.0, -0.05]), dim=-1) for _ in range(2))
    index = torch.arange(len(z)).repeat_interleave(len(wi))
    wi, wo = wi.repeat(len(z), 1), wo.repeat(len(z), 1)
    with torch.no_grad():
        mine, t_mine, _ = free.decoder(params[index], wi, wo)
        theirs, t_theirs, _ = ClosureForm(model.decoder, draws=64)(z[index], wi, wo)
    assert float((mine - theirs).abs().mean() / theirs.abs().mean()) < 0.04
    assert float((t_mine - t_theirs).abs().max()) < 0.01


def test_the_free_forms_gates_read_the_view_alone(model: NeuralModel) -> None:
    """Its gates change with wi and not with wo: a renderer's closures draw it exactly."""
    free = free_lobes.free_model(model)
    params = torch.randn(4, free_lobes.parameter_count(free))
    wi, wo, other = (torch.nn.functional.normalize(torch.rand(4, 3) + torch.tensor([0.0, 0.0, 0.3]), dim=-1)
                     for _ in range(3))
    with torch.no_grad():
        gates = free.decoder.gates_at(params, wi, wo)
        torch.testing.assert_close(gates, free.decoder.gates_at(params, wi, other))
        assert not torch.allclose(gates, free.decoder.gates_at(params, other, wo))


def test_fitting_the_free_form_lowers_the_decoders_loss_on_coated_metals(model: NeuralModel) -> None:
    """More freedom per material fits better: held-out loss below the decoder's own, gates and all."""
    metals = [c for c in cases(0, 2, 0) if "metal" in c.name][:2]
    vectors = np.stack([c.vector() for c in metals])
    with deterministic():
        z = fit_latents(model, vectors, 100, 1024, seed=0, per_vector=512)
        free, params = free_lobes.fit_free(model, vectors, z, 100, per_vector=512, batch=1024)
    decoder_loss = held_out_loss(model, vectors, z)
    free_loss = held_out_loss(free, vectors, params)
    assert free_loss < 0.9 * decoder_loss, (free_loss, decoder_loss)
