"""The conductor GGX closure kind (Gulbrandsen's n, k; multi_ggx): Fresnel, the (n, k) map, energy, sampler."""
from __future__ import annotations

import pytest
import torch

from tests.chi2 import sidak_threshold
from tests.closure_support import F64, direction, importance_integral, metal, probe, sampler_chi2, scalar
from torch_models.brdf import lobes
from torch_models.brdf.fresnel import fresnel_conductor, fresnel_dielectric

CASES = [(1e-3, 0.5), (0.05, 0.1), (0.05, 0.9), (0.3, 0.1), (0.3, 0.6), (1.0, 0.05), (1.0, 0.5),
         (1.0, 1.0)]


def test_conductor_fresnel_reduces_to_dielectric_and_normal_incidence() -> None:
    cos = torch.linspace(0.01, 1, 50, dtype=F64)[:, None]
    n = torch.tensor([[1.5, 2.0, 0.5]], dtype=F64)
    assert torch.allclose(fresnel_conductor(cos, n, torch.zeros_like(n))[:, :2],
                          fresnel_dielectric(cos, n[:, :2]), atol=1e-12)
    n, k = torch.tensor([[0.2, 1.1, 1.3]], dtype=F64), torch.tensor([[3.9, 2.5, 1.8]], dtype=F64)
    expected = ((n - 1) ** 2 + k ** 2) / ((n + 1) ** 2 + k ** 2)
    assert torch.allclose(fresnel_conductor(scalar(1.0), n, k), expected)


@pytest.mark.parametrize("g", [0.0, 0.25, 0.5, 0.75, 1.0])
def test_gulbrandsen_round_trip(g: float) -> None:
    r = torch.linspace(0.0, 0.99, 34, dtype=F64)[:, None].expand(-1, 3)
    n, k = lobes.gulbrandsen(r, torch.full_like(r, g))
    assert torch.allclose(fresnel_conductor(torch.ones_like(r[:, :1]), n, k), r, atol=1e-9)
    assert torch.isfinite(n).all() and (k >= 0).all()


def test_gulbrandsen_limits_and_clamp() -> None:
    r = torch.full((1, 3), 0.5, dtype=F64)
    n, k = lobes.gulbrandsen(r, torch.ones_like(r))
    assert torch.allclose(n, (1 - r) / (1 + r)) and torch.allclose(k, 2 * r.sqrt() / (1 + r))
    n, k = lobes.gulbrandsen(r, torch.zeros_like(r))
    assert torch.allclose(k, torch.zeros_like(k), atol=1e-7)
    high = lobes.gulbrandsen(torch.ones(1, 3, dtype=F64), torch.ones(1, 3, dtype=F64))
    assert torch.allclose(fresnel_conductor(scalar(1.0), *high), torch.full((1, 3), 0.99, dtype=F64))


@pytest.mark.parametrize("alpha,mu", CASES)
def test_conductor_integrates_to_its_albedo(alpha: float, mu: float) -> None:
    wi, a = direction(mu)[None], scalar(alpha)
    for g in (1.0, 0.5):
        n, k = metal(-1, g)
        total = importance_integral(wi, a, lambda wo: lobes.conductor_eval(wi, wo, a, n, k))
        albedo = lobes.conductor_albedo(scalar(mu), a, n, k)[0]
        assert (total <= 1.0).all()
        assert torch.allclose(total, albedo, atol=0.01), (g, total, albedo)


# GGX visible-normal sampling serves both GGX kinds; the dielectric's file runs the other half of the cases.
GGX_CHI2 = [(0.2, 0.5), (1.0, 0.5), (0.6, 1e-3)]


@pytest.mark.parametrize("alpha,mu", GGX_CHI2)
def test_conductor_sampler_chi2(alpha: float, mu: float) -> None:
    inputs = {"alpha": alpha, "reflectivity": (0.9, 0.5, 0.1), "edge_tint": 0.8}
    result = sampler_chi2(probe("conductor", inputs), direction(mu, 0.4), seed=11)
    assert result.passed(sidak_threshold(len(GGX_CHI2))), result
    assert result.pdf_integral == pytest.approx(result.accepted, abs=5e-3)
