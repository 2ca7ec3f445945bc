"""What the closures' formulas share: the Fss fits, finiteness, reciprocity, multi_ggx and the GGX pdf.

Each closure kind's own checks (its Fresnel, energy, sampler, fit) are in ``test_closure_<kind>.py``.
"""
from __future__ import annotations

import math
from typing import Callable, Iterator

import pytest
import torch
from torch import Tensor

from tests.chi2 import chi2_test, sidak_threshold
from tests.closure_support import F64, RGB_R, direction, hemisphere_rule, metal, scalar
from torch_models.brdf import lobes, tables
from torch_models.brdf.fresnel import conductor_fss, dielectric_fss, fresnel_conductor, fresnel_dielectric


@pytest.fixture(autouse=True, scope="module")
def one_thread() -> Iterator[None]:
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def test_fss_fits_match_the_cosine_weighted_mean() -> None:
    """Cycles' Fss are fits; check they are what they claim to approximate."""
    mu = torch.linspace(0, 1, 4001, dtype=F64)[:, None]
    ior = torch.tensor([[1.3, 1.5, 1.8]], dtype=F64)
    exact = torch.trapezoid(2 * mu * fresnel_dielectric(mu, ior), mu, dim=0)
    assert torch.allclose(dielectric_fss(ior)[0], exact, atol=6e-3)  # the fit is off by 0.0054 at 1.3
    n, k = metal(-1)
    exact = torch.trapezoid(2 * mu * fresnel_conductor(mu, n, k), mu, dim=0)
    # The F82 fit undershoots a g = 1 Gulbrandsen metal: 0.909/0.544/0.166 vs
    # 0.921/0.595/0.214 for r = (0.9, 0.5, 0.1). That is Cycles' Fss, kept as is.
    assert torch.allclose(conductor_fss(n, k)[0], exact, atol=0.06)
    assert (conductor_fss(n, k)[0] <= exact).all()


# ---- robustness ---------------------------------------------------------------------
def _extreme_pairs(dtype: torch.dtype) -> tuple[Tensor, Tensor, Tensor]:
    mus = [1e-6, 1e-3, 0.1, 0.7, 1.0]
    pairs = [(direction(a, 0.3), direction(b, p)) for a in mus for b in mus for p in (0.0, 2.0, math.pi)]
    wi = torch.stack([p[0] for p in pairs]).to(dtype)
    wo = torch.stack([p[1] for p in pairs]).to(dtype)
    u = torch.rand(len(pairs), 2, generator=torch.Generator().manual_seed(1), dtype=F64).to(dtype)
    return wi, wo, u


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("rough", [1e-4, 1e-3, 0.5, 1.0])
def test_everything_finite_and_non_negative(dtype: torch.dtype, rough: float) -> None:
    wi, wo, u = _extreme_pairs(dtype)
    a = torch.full((len(wi), 1), rough, dtype=dtype)
    ior = torch.full_like(a, 1.5)
    tint = torch.ones(len(wi), 3, dtype=dtype)
    n, k = lobes.gulbrandsen(torch.tensor([RGB_R], dtype=dtype).expand(len(wi), 3), tint)
    cos_i = wi[:, 2:3]
    outputs = [
        lobes.sheen_eval(wi, wo, a), lobes.sheen_pdf(wi, wo, a), lobes.sheen_albedo(cos_i, a),
        lobes.sheen_sample(wi, a, u),
        lobes.dielectric_eval(wi, wo, a, ior, tint), lobes.dielectric_albedo(cos_i, a, ior, tint),
        lobes.conductor_eval(wi, wo, a, n, k), lobes.conductor_albedo(cos_i, a, n, k),
        lobes.ggx_sample(wi, a, u), lobes.ggx_pdf(wi, wo, a),
    ]
    for i, out in enumerate(outputs):
        assert out.dtype == dtype, i
        assert torch.isfinite(out).all(), i
        if i not in (3, 8):  # directions may be negative
            assert (out >= 0).all(), i
    for wo_s in (outputs[3], outputs[8]):
        assert torch.allclose(wo_s.norm(dim=-1), torch.ones(len(wi), dtype=dtype), atol=1e-4)


def test_below_surface_is_zero() -> None:
    wi, wo = direction(0.5)[None], direction(-0.3, 1.0)[None]
    a, ior, tint = scalar(0.3), scalar(1.5), torch.ones(1, 3, dtype=F64)
    n, k = metal()
    for f in (lobes.sheen_eval(wi, wo, a), lobes.sheen_eval(wo, wi, a),
              lobes.dielectric_eval(wo, wi, a, ior, tint), lobes.conductor_eval(wi, wo, a, n, k),
              lobes.ggx_pdf(wi, wo, a), lobes.sheen_pdf(wi, wo, a)):
        assert (f == 0).all()


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
def test_cuda_matches_cpu() -> None:
    wi, wo, u = _extreme_pairs(torch.float32)
    a = torch.full((len(wi), 1), 0.4)
    cpu = lobes.sheen_eval(wi, wo, a) + lobes.ggx_pdf(wi, wo, a)
    gpu = lobes.sheen_eval(wi.cuda(), wo.cuda(), a.cuda()) + lobes.ggx_pdf(wi.cuda(), wo.cuda(), a.cuda())
    assert gpu.device.type == "cuda"
    assert torch.allclose(cpu, gpu.cpu(), rtol=1e-4, atol=1e-5)


# ---- reciprocity -----------------------------------------------------------------------
def _random_pairs(n: int = 256) -> tuple[Tensor, Tensor]:
    gen = torch.Generator().manual_seed(3)
    v = torch.randn(2, n, 3, generator=gen, dtype=F64)
    v[..., 2] = v[..., 2].abs() + 0.05
    v = v / v.norm(dim=-1, keepdim=True)
    return v[0], v[1]


@pytest.mark.parametrize("alpha", [0.05, 0.4, 1.0])
def test_single_scatter_is_reciprocal_and_multi_ggx_is_not(alpha: float) -> None:
    wi, wo = _random_pairs()
    a, ior, tint = scalar(alpha), scalar(1.5), torch.ones(1, 3, dtype=F64)
    n, k = metal(-1)
    for ev, fss in ((lambda x, y: lobes.dielectric_eval(x, y, a, ior, tint), dielectric_fss(ior)),
                    (lambda x, y: lobes.conductor_eval(x, y, a, n, k), conductor_fss(n, k))):
        f_io = ev(wi, wo) / wo[:, 2:3]
        f_oi = ev(wo, wi) / wi[:, 2:3]
        k_i = lobes.multi_ggx_factor(wi[:, 2:3], a, fss)
        k_o = lobes.multi_ggx_factor(wo[:, 2:3], a, fss)
        assert torch.allclose(f_io / k_i, f_oi / k_o, rtol=1e-9, atol=1e-12)
        assert not torch.allclose(f_io, f_oi, rtol=1e-3)


# ---- energy ----------------------------------------------------------------------------------
def test_multi_ggx_restores_white_furnace() -> None:
    """With Fss = 1 the factor is 1/E: a white lobe reflects everything."""
    alpha = torch.tensor([[0.01], [0.3], [1.0]], dtype=F64)
    mu = torch.tensor([[0.2], [0.6], [1.0]], dtype=F64)
    k = lobes.multi_ggx_factor(mu, alpha, torch.ones_like(mu))
    assert torch.allclose(k * tables.ggx_e(alpha, mu), torch.ones_like(mu))


@pytest.mark.parametrize("alpha,mu", [(0.1, 0.5), (0.5, 0.2), (1.0, 0.05), (1.0, 1.0)])
def test_ggx_pdf_integrates_to_the_accepted_fraction(alpha: float, mu: float) -> None:
    dirs, weights = hemisphere_rule(512, 512)
    wi, a = direction(mu), scalar(alpha)
    integral = float((lobes.ggx_pdf(wi.expand_as(dirs), dirs, a) * weights).sum())
    u = torch.rand(500_000, 2, generator=torch.Generator().manual_seed(2), dtype=F64)
    accepted = float((lobes.ggx_sample(wi.expand(len(u), 3), a, u)[:, 2] > 0).double().mean())
    assert integral <= 1.0 + 1e-3
    assert integral == pytest.approx(accepted, abs=3e-3)


# ---- samplers: chi-square ----------------------------------------------------------------------
def _sampler(sample: Callable[[Tensor, Tensor], Tensor], wi: Tensor, seed: int) -> Callable[[int], Tensor]:
    def fn(n: int) -> Tensor:
        u = torch.rand(n, 2, generator=torch.Generator().manual_seed(seed), dtype=F64)
        wo = sample(wi.expand(n, 3), u)
        return torch.where(wo[:, 2:3] > 0, wo, torch.full_like(wo, math.nan))  # Cycles rejects these
    return fn


def test_chi2_detects_a_wrong_pdf() -> None:
    """The helper must fail a sampler whose pdf is slightly off."""
    wi, a = direction(0.5), scalar(0.3)
    result = chi2_test(_sampler(lambda w, u: lobes.ggx_sample(w, a, u), wi, 5),
                       lambda wo: lobes.ggx_pdf(wi.expand_as(wo), wo, scalar(0.33))[:, 0])
    assert not result.passed(sidak_threshold(10))  # fails even at the level of ten sampler tests
