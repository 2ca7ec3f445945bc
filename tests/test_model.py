"""The layered model, Mitsuba-3 style: energy, T against the albedo above, sampling."""
from __future__ import annotations

import math

import pytest
import torch

from richmat_addon.core import graph as g
from richmat_addon.core.enhancement_types import TYPES
from richmat_addon.core.schema import PARAMS
from torch_models.brdf.model import LayeredBsdf, luminance
from tests.chi2 import chi2_test, sidak_threshold

# Which weights each enhancement type switches on (paper sec. 3.2).
TYPE_WEIGHTS = {
    0: {},
    1: {"dust_weight": 1.0},
    2: {"coat_weight": 1.0},
    3: {"dust_weight": 1.0, "coat_weight": 1.0},
    4: {"dust_weight": 1.0, "inner_weight": 1.0, "subsurf_weight": 1.0},
    5: {"dust_weight": 1.0, "coat_weight": 1.0, "inner_weight": 1.0, "subsurf_weight": 1.0},
}


def material(type_: int, roughness: float, metalness: float, base: float = 1.0,
             haze: float = 0.4) -> LayeredBsdf:
    """A constant material of one type; worst case for energy is a white base."""
    params = {}
    for p in PARAMS:
        d = p.default if isinstance(p.default, tuple) else (p.default,)
        params[p.name] = torch.tensor([d], dtype=torch.float64)
    params.update({k: torch.tensor([[v]], dtype=torch.float64) for k, v in {
        "alpha_core": max(roughness ** 3, 1e-4), "alpha_haze": min(1.0, 1.5 * roughness ** 1.5),
        "haze_weight": haze, "metalness": metalness, "dust_roughness": 0.6,
        "inner_roughness": 0.4, "subsurf_alpha": 0.7, **TYPE_WEIGHTS[type_]}.items()})
    params["spec_color"] = torch.tensor([[0.95, 0.9, 0.8]], dtype=torch.float64)
    return LayeredBsdf(params, torch.full((1, 3), base, dtype=torch.float64))


def directional_albedo(bsdf: LayeredBsdf, cos_i: float, n: int = 128) -> torch.Tensor:
    """Integral of f * cos over the hemisphere at one view direction, by quadrature (RGB)."""
    import numpy as np
    x, w = np.polynomial.legendre.leggauss(n)
    mu = torch.from_numpy((x + 1) / 2)
    phi = torch.from_numpy((x + 1) * math.pi)
    wmu, wphi = torch.from_numpy(w / 2), torch.from_numpy(w * math.pi)
    M, P = torch.meshgrid(mu, phi, indexing="ij")
    s = (1 - M ** 2).clamp(min=0).sqrt()
    wo = torch.stack([s * P.cos(), s * P.sin(), M], -1).reshape(-1, 3)
    wi = torch.tensor([[math.sqrt(1 - cos_i ** 2), 0.0, cos_i]], dtype=torch.float64).expand_as(wo)
    f = bsdf.eval(wi, wo).reshape(n, n, 3)
    return (f * (wmu[:, None] * wphi[None, :])[..., None]).sum((0, 1))


FURNACE_GRID = [(t.index, r, m) for t in TYPES for r in (0.02, 0.15, 0.5, 1.0)
                for m in ((0.0,) if t.dielectric_only else (0.0, 0.5, 1.0))]


@pytest.mark.parametrize("type_,roughness,metalness", FURNACE_GRID)
def test_white_furnace_every_type(type_, roughness, metalness):
    """Analytic white furnace: with a white base no view direction gains energy."""
    bsdf = material(type_, roughness, metalness)
    for cos_i in (1.0, 0.5, 0.1):
        albedo = directional_albedo(bsdf, cos_i)
        assert torch.isfinite(albedo).all()
        # 1 % margin: the quadrature of a rough-but-peaked lobe, and Cycles' own
        # multi_ggx factor (k = 1/E at F = 1) that the lobes reproduce.
        assert albedo.max() <= 1.01, (type_, roughness, metalness, cos_i, albedo)


def test_transmission_is_one_minus_albedo_above():
    """A dust layer over a white diffuse: T = 1 - w R(mu) and the energy adds up."""
    bsdf = material(1, 0.5, 0.0)
    only_dust = LayeredBsdf(bsdf.params, bsdf.base_color, g.Layer(g.DUST, g.Diffuse()))
    for cos_i in (1.0, 0.3):
        wi = torch.tensor([[math.sqrt(1 - cos_i ** 2), 0.0, cos_i]], dtype=torch.float64)
        per_lobe, _ = only_dust.lobe_albedos(wi)
        t = only_dust.transmission(wi)
        assert torch.allclose(t, 1 - per_lobe[0].amax(-1, keepdim=True))
        total = directional_albedo(only_dust, cos_i)
        assert torch.allclose(total, per_lobe[0] + t, atol=2e-3)


def test_reflectance_matches_integrated_non_diffuse_part():
    bsdf = material(5, 0.4, 0.0)
    neural_only = LayeredBsdf(bsdf.params, torch.zeros(1, 3, dtype=torch.float64))
    wi = torch.tensor([[0.6, 0.0, 0.8]], dtype=torch.float64)
    integral = luminance(directional_albedo(neural_only, 0.8)[None])
    assert abs(float(integral) - float(bsdf.reflectance(wi))) < 0.02


def test_pruning_skips_disabled_lobes():
    assert [l.name for l in material(0, 0.5, 0.0).lobes] == ["diel_core", "diel_haze"]
    assert len(material(5, 0.5, 0.0).lobes) == 6
    assert len(material(3, 0.5, 0.5).lobes) == 6


@pytest.mark.parametrize("type_,metalness,cos_i", [(0, 0.5, 0.9), (3, 0.5, 0.4), (5, 0.0, 0.7),
                                                   (4, 0.0, 0.15)])
def test_chi2_whole_model(type_, metalness, cos_i):
    torch.manual_seed(1)
    bsdf = material(type_, 0.45, metalness, base=0.5)
    wi1 = torch.tensor([[math.sqrt(1 - cos_i ** 2), 0.0, cos_i]], dtype=torch.float64)

    def sample(n):
        wo = bsdf.sample(wi1.expand(n, 3), torch.rand(n, 3, dtype=torch.float64))
        return torch.where(wo[:, 2:3] > 0, wo, torch.full_like(wo, float("nan")))

    result = chi2_test(sample, lambda wo: bsdf.pdf(wi1.expand_as(wo), wo), n_samples=100_000)
    assert result.passed(sidak_threshold(4)), result
