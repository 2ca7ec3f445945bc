"""Glints (paper sec. 5.4): the simplex noise and the f_neu multiplier built from it."""
from __future__ import annotations

import torch

from torch_models.neural.bsdf import NeuralBsdf
from torch_models.neural.glints import GlintPattern, SimplexNoise3
from torch_models.neural.loss import LOSS_WEIGHTS
from torch_models.neural.mlp.networks import Decoder, SamplingDecoder
from torch_models.neural.networks import Encoder
from torch_models.neural.model import NeuralModel


def _points(n: int, seed: int = 1, spread: float = 50.0) -> torch.Tensor:
    return spread * torch.rand(n, 3, generator=torch.Generator().manual_seed(seed))


def _directions(n: int, seed: int) -> torch.Tensor:
    w = torch.randn(n, 3, generator=torch.Generator().manual_seed(seed))
    w[:, 2] = w[:, 2].abs() + 0.1
    return w / w.norm(dim=-1, keepdim=True)


def test_noise_is_deterministic_per_seed_finite_and_in_range() -> None:
    p = _points(20000)
    a, b, c = SimplexNoise3(3)(p), SimplexNoise3(3)(p), SimplexNoise3(4)(p)
    assert torch.equal(a, b) and not torch.equal(a, c)
    assert torch.isfinite(a).all() and a.abs().max() <= 1.0
    assert a.abs().max() > 0.5 and abs(float(a.mean())) < 0.02  # uses its range, centred


def test_noise_is_continuous_across_simplex_boundaries() -> None:
    noise = SimplexNoise3(0)
    line = torch.linspace(0.0, 20.0, 200001)[:, None] * torch.tensor([[0.37, 0.71, 0.13]])
    v = noise(line)
    step = float((line[1] - line[0]).norm())
    assert float((v[1:] - v[:-1]).abs().max()) < 20.0 * step  # Lipschitz: no seams


def test_glint_multiplier_range_mean_and_colour() -> None:
    pattern = GlintPattern(scale=1.0, strength=0.8, seed=2)
    m = pattern(_points(100000, spread=200.0))
    lo, hi = pattern.range
    assert m.shape == (100000, 3) and torch.isfinite(m).all()
    assert m.min() >= lo - 1e-6 and m.max() <= hi + 1e-4
    assert torch.allclose(m.mean(0), torch.ones(3), atol=0.05)  # energy kept on average
    # Wavelength-dependent: the channels sparkle at different places.
    assert float(torch.corrcoef(m.T)[0, 2]) < 0.5
    assert torch.equal(m, GlintPattern(scale=1.0, strength=0.8, seed=2)(_points(100000, spread=200.0)))


def test_glints_are_continuous_and_follow_the_half_vector() -> None:
    pattern = GlintPattern(scale=1.0, strength=1.0, seed=0)
    p = _points(5000)
    near = pattern(p + 1e-4)
    assert float((near - pattern(p)).abs().max()) < 0.05 * pattern.range[1]
    wi, wo = _directions(5000, 1), _directions(5000, 2)
    assert not torch.allclose(pattern(p, wi, wo), pattern(p, wi, wi))


def test_zero_strength_leaves_the_neural_bsdf_unchanged() -> None:
    torch.manual_seed(0)
    model = NeuralModel(Encoder(), Decoder(64, 4), SamplingDecoder(), "untrained", 0.0, 0.0, LOSS_WEIGHTS[1])
    n = 4096
    p = _directions(n, 3)
    wi, wo = _directions(n, 4), _directions(n, 5)
    latent, base = torch.rand(1, 6) * 2 - 1, torch.tensor([[0.5, 0.3, 0.2]])
    plain = NeuralBsdf(model, latent, base, 0.9)
    with torch.no_grad():
        off = NeuralBsdf(model, latent, base, 0.9, GlintPattern(strength=0.0).at(p)).eval(wi, wo)
        on = NeuralBsdf(model, latent, base, 0.9, GlintPattern(strength=0.7).at(p)).eval(wi, wo)
        assert torch.equal(off, plain.eval(wi, wo))
        assert not torch.allclose(on, plain.eval(wi, wo))
