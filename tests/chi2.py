"""Chi-square goodness-of-fit test of a direction sampler against its pdf.

Mitsuba-3-style (``mitsuba.python.chi2``), usable for any sampler on the sphere:
one lobe, a mixture, the whole layered model.

- The sphere is cut into ``res = (n_cos, n_phi)`` cells uniform in cos(theta) in
  [-1, 1] and phi in [-pi, pi] (equal solid angle each).
- Expected counts: n_samples * the integral of the pdf over each cell, by a
  Gauss-Legendre rule of ``ires x ires`` nodes per cell (in cos theta and phi, where
  d(omega) = d(cos theta) d(phi) exactly).
- Observed counts: histogram of the samples. Rows of NaN mark rejected samples
  (e.g. a microfacet reflection below the surface, which Cycles discards): they
  are not binned but still count in n_samples, so a pdf that integrates to the
  accepted fraction is the right one.
- Cells whose expected count is below ``min_expected`` are pooled (in order of
  increasing expectation) until the pool reaches it; Pearson's statistic over the
  remaining cells and the pool gives a p-value from scipy.stats.chi2.sf with
  (cells - 1) degrees of freedom.
- A sample in a cell of exactly zero expected mass fails outright (p = 0).

Run many tests with ``sidak_threshold(n_tests)`` as the pass level.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
import torch
from scipy import stats
from torch import Tensor

SampleFn = Callable[[int], Tensor]  # n -> (n, 3) unit directions, NaN rows = rejected
PdfFn = Callable[[Tensor], Tensor]  # (m, 3) directions -> (m,) solid-angle density


@dataclass(frozen=True)
class Chi2Result:
    p_value: float
    statistic: float
    dof: int
    pdf_integral: float  # integral of the pdf over the sphere
    accepted: float  # fraction of samples that were not rejected

    def passed(self, threshold: float) -> bool:
        return self.p_value > threshold


def sidak_threshold(n_tests: int, significance: float = 0.01) -> float:
    """Per-test level keeping the family-wise error at ``significance`` (~ significance / n)."""
    return 1.0 - (1.0 - significance) ** (1.0 / n_tests)


def _cell_rule(res: tuple[int, int], ires: int) -> tuple[Tensor, Tensor]:
    """Directions (n_cos, n_phi, ires^2, 3) and weights (same minus the 3) of the per-cell rule."""
    x, w = np.polynomial.legendre.leggauss(ires)
    x, w = torch.from_numpy((x + 1.0) / 2.0), torch.from_numpy(w / 2.0)
    n_cos, n_phi = res
    d_cos, d_phi = 2.0 / n_cos, 2.0 * math.pi / n_phi
    cos = -1.0 + (torch.arange(n_cos, dtype=torch.float64)[:, None] + x[None]) * d_cos  # (n_cos, ires)
    phi = -math.pi + (torch.arange(n_phi, dtype=torch.float64)[:, None] + x[None]) * d_phi
    cos_g = cos[:, None, :, None].expand(n_cos, n_phi, ires, ires)
    phi_g = phi[None, :, None, :].expand(n_cos, n_phi, ires, ires)
    sin_g = (1.0 - cos_g ** 2).clamp(min=0.0).sqrt()
    dirs = torch.stack([sin_g * phi_g.cos(), sin_g * phi_g.sin(), cos_g], -1)
    weights = (w[:, None] * w[None, :]) * d_cos * d_phi
    return dirs.reshape(n_cos, n_phi, ires * ires, 3), weights.reshape(-1).expand(n_cos, n_phi, -1)


def expected_mass(pdf_fn: PdfFn, res: tuple[int, int], ires: int) -> Tensor:
    """Integral of the pdf over every cell, (n_cos, n_phi), float64."""
    dirs, weights = _cell_rule(res, ires)
    values = pdf_fn(dirs.reshape(-1, 3)).reshape(weights.shape).to(torch.float64)
    return (values * weights).sum(-1)


def observed_counts(wo: Tensor, res: tuple[int, int]) -> Tensor:
    """Histogram of directions over the cells; NaN rows are skipped, (n_cos, n_phi)."""
    wo = wo.detach().to(torch.float64)
    wo = wo[~wo.isnan().any(-1)]
    n_cos, n_phi = res
    i = ((wo[:, 2].clamp(-1.0, 1.0) + 1.0) / 2.0 * n_cos).long().clamp(0, n_cos - 1)
    phi = torch.atan2(wo[:, 1], wo[:, 0])
    j = ((phi + math.pi) / (2.0 * math.pi) * n_phi).long().clamp(0, n_phi - 1)
    counts = torch.zeros(n_cos * n_phi, dtype=torch.float64)
    counts.index_add_(0, i * n_phi + j, torch.ones_like(phi))
    return counts.reshape(res)


def pearson(observed: np.ndarray, expected: np.ndarray, min_expected: float) -> tuple[float, int]:
    """Pearson's statistic with Mitsuba's pooling of low-expectation cells; (stat, dof)."""
    if np.any((expected == 0) & (observed > 0)):
        return math.inf, 1
    statistic, cells = 0.0, 0
    pool_obs = pool_exp = 0.0
    for idx in np.argsort(expected, kind="stable"):
        if expected[idx] < min_expected or 0 < pool_exp < min_expected:
            pool_obs += observed[idx]
            pool_exp += expected[idx]
        else:
            statistic += (observed[idx] - expected[idx]) ** 2 / expected[idx]
            cells += 1
    if pool_exp > 0:
        statistic += (pool_obs - pool_exp) ** 2 / pool_exp
        cells += 1
    return statistic, max(cells - 1, 1)


def chi2_test(sample_fn: SampleFn, pdf_fn: PdfFn, n_samples: int = 200_000,
              res: tuple[int, int] = (32, 64), ires: int = 6,
              min_expected: float = 5.0) -> Chi2Result:
    """Compare ``sample_fn(n_samples)`` with ``pdf_fn`` on the sphere; see the module doc."""
    mass = expected_mass(pdf_fn, res, ires)
    wo = sample_fn(n_samples)
    observed = observed_counts(wo, res)
    statistic, dof = pearson(observed.reshape(-1).numpy(), (mass * n_samples).reshape(-1).numpy(),
                             min_expected)
    p_value = 0.0 if math.isinf(statistic) else float(stats.chi2.sf(statistic, dof))
    return Chi2Result(p_value, float(statistic), dof, float(mass.sum()),
                      float(observed.sum()) / n_samples)
