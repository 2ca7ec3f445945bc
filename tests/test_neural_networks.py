"""The neural material's networks: shapes, ranges, and an exact sampling pdf."""
from __future__ import annotations

import math

import pytest
import torch

from richmat_addon.core.schema import bounds, default_vector
from torch_models.neural.mlp.networks import Decoder, SamplingDecoder
from torch_models.neural.networks import LATENT, Encoder, direction_features
from tests.chi2 import chi2_test, sidak_threshold

CASES = [(0, 0.9), (1, 0.4), (2, 0.08)]  # (network seed, cos theta_i)
THRESHOLD = sidak_threshold(len(CASES))


def _unit(n: int, gen: torch.Generator) -> torch.Tensor:
    v = torch.randn(n, 3, generator=gen, dtype=torch.float64)
    v[:, 2] = v[:, 2].abs()
    return v / v.norm(dim=-1, keepdim=True)


def test_encoder_latents_stay_in_the_box() -> None:
    lo, hi = (torch.tensor(b, dtype=torch.float64) for b in bounds())
    gen = torch.Generator().manual_seed(0)
    vectors = torch.cat([lo + (hi - lo) * torch.rand(500, len(lo), generator=gen, dtype=torch.float64),
                         torch.tensor([default_vector()], dtype=torch.float64)])
    z = Encoder().double()(vectors)
    assert z.shape == (501, LATENT) and (z.abs() < 1).all()


def test_decoder_outputs_are_finite_bounded_and_zero_below_the_horizon() -> None:
    gen = torch.Generator().manual_seed(1)
    dec = Decoder(64, 4).double()
    z = 1.1 * (2 * torch.rand(1000, LATENT, generator=gen, dtype=torch.float64) - 1)  # box + 10 %
    wi, wo = _unit(1000, gen), _unit(1000, gen)
    wo[:500, 2] *= -1  # below the horizon
    f, t, r = dec(z, wi, wo)
    assert f.shape == (1000, 3) and t.shape == (1000, 1) and r.shape == (1000, 1)
    assert torch.isfinite(f).all() and (f >= 0).all() and (f[:500] == 0).all()
    assert ((t >= 0) & (t <= 1)).all() and ((r >= 0) & (r <= 1)).all()


def test_direction_features_are_wi_wo_the_half_vector_and_wi_dot_h() -> None:
    """For wo = wi the half vector is wi itself and wi.h is 1; for a mirror pair it is the normal."""
    theta = torch.tensor([0.0, 1e-3, 0.3, 1.2], dtype=torch.float64)
    wi = torch.stack([theta.sin(), torch.zeros_like(theta), theta.cos()], -1)
    same = direction_features(wi, wi)
    assert same.shape == (4, 10) and torch.equal(same[:, :3], wi) and torch.equal(same[:, 3:6], wi)
    assert torch.allclose(same[:, 6:9], wi) and torch.allclose(same[:, 9], torch.ones(4, dtype=torch.float64))
    mirror = wi * torch.tensor([-1.0, -1.0, 1.0], dtype=torch.float64)
    h = direction_features(wi, mirror)[:, 6:9]
    assert torch.allclose(h, torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64).expand(4, 3))


@pytest.mark.parametrize("seed,mu", CASES)
def test_sampling_decoder_pdf_matches_its_samples(seed: int, mu: float) -> None:
    torch.manual_seed(seed)
    sampler = SamplingDecoder().double()
    z = torch.rand(1, LATENT, dtype=torch.float64) * 2 - 1
    wi = torch.tensor([[math.sqrt(1 - mu * mu), 0.0, mu]], dtype=torch.float64)

    def sample(n: int) -> torch.Tensor:
        u = torch.rand(n, 3, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)
        wo = sampler.sample(z.expand(n, LATENT), wi.expand(n, 3), u)
        return torch.where(wo[:, 2:3] > 0, wo, torch.full_like(wo, math.nan))

    with torch.no_grad():
        result = chi2_test(sample, lambda wo: sampler.pdf(z.expand(len(wo), LATENT), wi.expand(len(wo), 3), wo))
    assert result.passed(THRESHOLD), result
    assert result.pdf_integral == pytest.approx(result.accepted, abs=5e-3)
