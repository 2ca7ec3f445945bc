"""The Lambertian base's closure kind: its cosine sampler, its energy, and how the layered model weights it."""
from __future__ import annotations

import math

import pytest
import torch

from richmat_addon.core import graph
from tests.chi2 import sidak_threshold
from tests.closure_support import direction, hemisphere_rule, material, sampler_chi2

DIFFUSE_CHI2 = [17, 23]  # seeds: the cosine sampler does not depend on the view direction


@pytest.mark.parametrize("seed", DIFFUSE_CHI2)
def test_diffuse_sampler_chi2(seed: int) -> None:
    result = sampler_chi2(graph.Diffuse(), direction(0.4, 1.0), seed=seed)
    assert result.passed(sidak_threshold(len(DIFFUSE_CHI2))), result
    assert result.pdf_integral == pytest.approx(1.0, abs=5e-3)


@pytest.mark.parametrize("mu", [0.05, 0.5, 1.0])
def test_a_white_diffuse_reflects_everything_and_a_grey_one_its_colour(mu: float) -> None:
    dirs, weights = hemisphere_rule()
    wi = direction(mu, 0.3).expand_as(dirs)
    for grey in (1.0, 0.35):
        bsdf = material(graph.Diffuse(), base_color=grey)
        total = (bsdf.eval(wi, dirs) * weights).sum(0)
        assert torch.allclose(total, torch.full((3,), grey, dtype=total.dtype), atol=1e-6)
        assert float(bsdf.transmission(wi[:1])) == 1.0  # nothing above it
        assert float(bsdf.reflectance(wi[:1])) == 0.0  # it is not part of f_neu
    assert float((material(graph.Diffuse(), 1.0).eval(-wi, dirs)).abs().sum()) == 0.0  # seen from below: black
    assert float((material(graph.Diffuse()).pdf(wi, dirs)[:, None] * weights).sum()) == pytest.approx(1.0, abs=1e-9)
    assert math.isclose(float(material(graph.Diffuse()).pdf(wi[:1], torch.tensor([[0.0, 0.0, 1.0]],
                        dtype=wi.dtype))), 1.0 / math.pi)
