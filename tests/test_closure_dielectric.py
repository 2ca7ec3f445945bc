"""The dielectric GGX closure kind (reflection only, multi_ggx): Fresnel, energy, sampler and albedo fit."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from richmat_addon.core import graph
from richmat_addon.core.closures import dielectric
from tests.chi2 import sidak_threshold
from tests.closure_support import F64, direction, importance_integral, probe, sampler_chi2, scalar
from torch_models.brdf import lobes, tables
from torch_models.brdf.fresnel import dielectric_fss, f0_from_ior, fresnel_dielectric

CASES = [(1e-3, 0.5), (0.05, 0.1), (0.05, 0.9), (0.3, 0.1), (0.3, 0.6), (1.0, 0.05), (1.0, 0.5),
         (1.0, 1.0)]


def test_dielectric_fresnel_known_values() -> None:
    ior = torch.tensor([1.5, 1.33, 1.8], dtype=F64)
    assert torch.allclose(fresnel_dielectric(torch.ones(3, dtype=F64), ior), f0_from_ior(ior))
    assert abs(float(fresnel_dielectric(scalar(1.0), scalar(1.5))) - 0.04) < 1e-12
    # Grazing incidence reflects everything; inside (eta < 1) beyond the critical angle: TIR.
    assert float(fresnel_dielectric(scalar(0.0), scalar(1.5))) == pytest.approx(1.0)
    critical = math.sqrt(1 - (1 / 1.5) ** 2)
    assert float(fresnel_dielectric(scalar(critical - 1e-3), scalar(1 / 1.5))) == 1.0
    assert float(fresnel_dielectric(scalar(critical + 1e-2), scalar(1 / 1.5))) < 1.0
    # Brewster: Rp = 0, so F = Rs / 2 = ((n^2 - 1) / (n^2 + 1))^2 / 2.
    brewster = math.cos(math.atan(1.5))
    assert float(fresnel_dielectric(scalar(brewster), scalar(1.5))) == pytest.approx(
        0.5 * ((1.5 ** 2 - 1) / (1.5 ** 2 + 1)) ** 2, rel=1e-9)


@pytest.mark.parametrize("alpha,mu", CASES)
def test_dielectric_layering_albedo_tracks_its_integral(alpha: float, mu: float) -> None:
    """Cycles' layering estimate tint [F0 + (1-F0) s] k E vs the true albedo k int F f_ss.

    They differ by how s weights microfacets (plain VNDF mean, not G2/G1-weighted):
    measured within 0.01 absolute (0.03 relative) on these cases.
    """
    wi, a, ior = direction(mu)[None], scalar(alpha), scalar(1.5)
    tint = torch.tensor([[1.0, 0.6, 0.2]], dtype=F64)
    total = importance_integral(wi, a, lambda wo: lobes.dielectric_eval(wi, wo, a, ior, tint))
    albedo = lobes.dielectric_albedo(scalar(mu), a, ior, tint)[0]
    assert (total <= 1.0).all()
    assert torch.allclose(total, albedo, atol=0.01, rtol=0.03), (total, albedo)


def test_dielectric_albedo_is_cycles_estimate_times_darkening() -> None:
    mu, a, ior = scalar(0.4), scalar(0.2), scalar(1.45)
    tint = torch.tensor([[1.0, 0.5, 0.0]], dtype=F64)
    f0 = f0_from_ior(ior)
    s = tables.gen_schlick_ior_s(a, mu, ior)
    e = tables.ggx_e(a, mu)
    fss = dielectric_fss(ior) * tint
    e_avg = tables.ggx_eavg(a)
    fms = fss * e_avg / (1 - fss * (1 - e_avg))
    expected = tint * (f0 + (1 - f0) * s) * (e + fms * (1 - e))
    assert torch.allclose(lobes.dielectric_albedo(mu, a, ior, tint), expected)


# GGX visible-normal sampling serves both GGX kinds; the conductor's file runs the other half of the cases.
GGX_CHI2 = [(0.05, 0.9), (0.5, 0.05), (1.0, 1.0)]


@pytest.mark.parametrize("alpha,mu", GGX_CHI2)
def test_dielectric_sampler_chi2(alpha: float, mu: float) -> None:
    inputs = {"alpha": alpha, "ior": 1.5, "tint": graph.WHITE}
    result = sampler_chi2(probe("dielectric", inputs), direction(mu, 0.4), seed=11)
    assert result.passed(sidak_threshold(len(GGX_CHI2))), result
    assert result.pdf_integral == pytest.approx(result.accepted, abs=5e-3)


def test_the_fit_follows_the_torch_tables() -> None:
    rng = np.random.default_rng(0)
    mu, rho, ior = rng.uniform(0.1, 1, 400), rng.uniform(0.01, 1, 400), rng.uniform(1.3, 1.8, 400)
    t = {k: torch.from_numpy(v)[:, None] for k, v in {"mu": mu, "alpha": rho ** 2, "ior": ior}.items()}
    with torch.no_grad():
        table = lobes.dielectric_albedo(t["mu"], t["alpha"], t["ior"], torch.ones(400, 3, dtype=F64))[:, 0].numpy()
    fitted = np.array([dielectric.fitted_albedo(m, r * r, n) for m, r, n in zip(mu, rho, ior)])
    assert np.abs(fitted - table).max() <= dielectric.ALBEDO_FIT.max_error + 1e-3
    assert not math.isnan(dielectric.fitted_albedo(0.0, 0.0, 1.5))  # grazing and smooth: finite
