"""The regenerated Cycles lookup tables: conventions, published values, determinism."""
from __future__ import annotations

import math
from typing import Iterator

import pytest
import numpy as np
import torch

from richmat_addon.core.sheen_table import sheen_table
from torch_models.brdf import ggx, tables
from torch_models.brdf.frame import cos_theta, reflect
from torch_models.brdf.fresnel import f0_from_ior, fresnel_dielectric

F64 = torch.float64

# Published Cycles values (scene/shader.tables, table_ggx_E[mu][rough] and
# table_ggx_Eavg[rough]), used only to check our regenerated tables.
# (mu node, rough node) -> E
PUBLISHED_E = {
    (3, 16): 0.893246, (3, 31): 0.765057, (16, 16): 0.847421, (16, 31): 0.443841,
    (31, 5): 0.999296, (31, 11): 0.980785, (31, 16): 0.903873, (31, 24): 0.592102,
    (31, 31): 0.306853, (1, 3): 0.954714, (1, 31): 0.888202, (0, 1): 0.980405,
}
PUBLISHED_EAVG = {4: 0.998729, 10: 0.970160, 16: 0.870874, 22: 0.697631, 31: 0.409137}
# brdf-notes sec. 2: Cycles' sheen albedo R at roughness nodes 1, 16/31, 8/31.
PUBLISHED_SHEEN_R = {
    (31, 3): 0.70, (31, 15.5): 0.49, (31, 31): 0.34,
    (16, 3): 0.56, (16, 15.5): 0.16, (16, 31): 0.02,
    (8, 3): 0.40, (8, 15.5): 0.007, (8, 31): 0.0003,
}


@pytest.fixture(autouse=True, scope="module")
def one_thread() -> Iterator[None]:
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def test_lookup_is_node_centred_bilinear_and_clamped() -> None:
    table = torch.arange(12, dtype=F64).reshape(3, 4)  # y: 3 nodes, x: 4 nodes
    x = torch.tensor([0.0, 1 / 3, 0.5, 1.0, -2.0, 5.0], dtype=F64)
    y = torch.tensor([0.0, 0.5, 0.25, 1.0, 0.0, 1.0], dtype=F64)
    # value = 4 * y_index + x_index, linear in both, so bilinear reads are exact.
    expected = 4 * (y.clamp(0, 1) * 2) + x.clamp(0, 1) * 3
    assert torch.allclose(tables.lookup(table, x, y), expected)


def test_ggx_e_matches_published_cycles_values() -> None:
    e = tables.table("ggx_E", torch.device("cpu"), F64)
    errors = {k: abs(float(e[k]) - v) for k, v in PUBLISHED_E.items()}
    assert max(errors.values()) < 1e-3, errors


def test_ggx_e_notes_values_at_alpha_one() -> None:
    """brdf-notes sec. 3.3: 0.765 / 0.444 / 0.307 (the mu nodes 3/31, 16/31, 1)."""
    alpha = torch.ones(3, dtype=F64)
    mu = torch.tensor([3 / 31, 16 / 31, 1.0], dtype=F64)
    got = tables.ggx_e(alpha, mu)
    assert torch.allclose(got, torch.tensor([0.765, 0.444, 0.307], dtype=F64), atol=1.5e-3)


def _albedo_grid(rough: torch.Tensor, mu: torch.Tensor) -> torch.Tensor:
    """Single-scatter GGX albedo on a (mu, rough) grid by the tables' own quadrature, at 64 nodes."""
    weight, _, rule = tables.vndf_quadrature(rough, mu, 64)
    return (rule * weight).sum(-1)


def test_upper_table_read_never_falls_short_of_the_albedo() -> None:
    """Between its nodes Cycles' table reads up to 0.86 % short (the hybrid's unit lobes then gain
    energy); the upper table's bilinear read covers the albedo at points off its nodes and its
    evaluation grid, and raises the table by little."""
    gen = torch.Generator().manual_seed(3)
    upper = tables.table("ggx_E_upper", torch.device("cpu"), F64)
    cycles = tables.table("ggx_E", torch.device("cpu"), F64)
    shortest = {}
    for name, span in (("everywhere", 1.0), ("smooth, grazing", 0.1)):  # the steepest corner, sampled densely
        rough = (torch.rand(48, generator=gen, dtype=F64) * span).clamp(1e-4, 1.0)
        mu = (torch.rand(48, generator=gen, dtype=F64) * span).clamp(1e-4, 1.0)
        albedo = _albedo_grid(rough, mu)
        r, m = torch.meshgrid(rough, mu, indexing="xy")
        shortest[name] = (float((albedo / tables.lookup(upper, r, m)).max()),
                          float((albedo / tables.lookup(cycles, r, m)).max()))
    assert all(u <= 1.0 for u, _ in shortest.values()), shortest
    assert max(c for _, c in shortest.values()) > 1.002, shortest  # the points find Cycles' shortfall
    raised = (upper - cycles) / cycles
    assert (raised >= 0).all() and raised.mean() < 2e-3 and raised.max() < 0.012


def test_ggx_eavg_matches_published_cycles_values() -> None:
    eavg = tables.table("ggx_Eavg", torch.device("cpu"), F64)
    for node, value in PUBLISHED_EAVG.items():
        assert abs(float(eavg[node]) - value) < 5e-4, node


def test_eavg_is_cosine_weighted_mean_of_e() -> None:
    e = tables.table("ggx_E", torch.device("cpu"), F64)
    mu = tables.nodes(tables.E_SIZE, 0.0)
    trapezoid = torch.trapezoid(2.0 * mu[:, None] * e, mu, dim=0)
    assert torch.allclose(trapezoid, tables.table("ggx_Eavg", torch.device("cpu"), F64), atol=2e-3)


def test_gen_schlick_s_smooth_limit_is_the_fresnel_ratio() -> None:
    """At rough ~ 0 every microfacet is the normal: s = (F(mu) - F0) / (1 - F0)."""
    s = tables.table("ggx_gen_schlick_ior_s", torch.device("cpu"), F64)[:, :, 0]  # [z][mu]
    ior = tables.ior_from_z(tables.nodes(tables.S_SIZE, 1e-4, 0.99))[:, None]
    mu = tables.nodes(tables.S_SIZE)[None, :]
    f0 = f0_from_ior(ior)
    expected = ((fresnel_dielectric(mu, ior) - f0) / (1.0 - f0)).clamp(0, 1)
    assert torch.allclose(s, expected, atol=1e-6)


@pytest.mark.parametrize("node", [(10, 5, 8), (4, 12, 3), (15, 15, 1), (7, 1, 14)])
def test_gen_schlick_s_matches_monte_carlo(node: tuple[int, int, int]) -> None:
    """Our quadrature vs a plain VNDF Monte Carlo of Cycles' definition (invalid samples = 0)."""
    z, m, r = node
    rough = float(tables.nodes(tables.S_SIZE)[r])
    mu = float(tables.nodes(tables.S_SIZE)[m])
    ior = float(tables.ior_from_z(tables.nodes(tables.S_SIZE, 1e-4, 0.99))[z])
    gen = torch.Generator().manual_seed(7)
    u = torch.rand(400_000, 2, generator=gen, dtype=F64)
    wi = torch.tensor([math.sqrt(1 - mu * mu), 0.0, mu], dtype=F64).expand(len(u), 3)
    alpha = torch.tensor([[rough * rough]], dtype=F64)
    h = ggx.ggx_sample_vndf(wi, alpha, u)
    ratio = (fresnel_dielectric((wi * h).sum(-1, keepdim=True), torch.tensor(ior, dtype=F64))
             - f0_from_ior(torch.tensor(ior))) / (1 - f0_from_ior(torch.tensor(ior)))
    mc = (ratio.clamp(0, 1) * (cos_theta(reflect(wi, h)) > 0)).mean()
    ours = tables.table("ggx_gen_schlick_ior_s", torch.device("cpu"), F64)[z, m, r]
    assert abs(float(mc - ours)) < 2e-3


def test_sheen_table_against_published_cycles_values() -> None:
    """Hill's fits vs Cycles' own table (brdf-notes sec. 2): within 0.02 (sec. 5.2)."""
    for (r_node, mu_node), value in PUBLISHED_SHEEN_R.items():
        r = torch.tensor(r_node / 31, dtype=F64)
        mu = torch.tensor(mu_node / 31, dtype=F64)
        got = float(tables.sheen_ltc(mu, r)[2])
        assert abs(got - value) < 0.02, (r_node, mu_node, got, value)


def test_sheen_table_is_the_calibrated_file_read_bilinearly() -> None:
    """The shipped table (bench/material/calibrate_sheen.py) is read at nodes exactly, and it stays
    within the documented distance of Hill's fits where it was measured (mu >= 0.2) and
    sheen is visible (R > 0.01)."""
    t = tables.table("sheen_ltc", torch.device("cpu"), F64)
    assert torch.equal(t, torch.from_numpy(sheen_table()).to(F64))
    node = tables.sheen_ltc(torch.tensor(9 / 31, dtype=F64), torch.tensor(19 / 31, dtype=F64))
    assert torch.allclose(torch.stack(node), t[:, 19, 9])
    hill = tables.hill_sheen_ltc()
    visible = hill[2] > 0.01
    visible[:, :7] = False  # mu < 0.2: not measured, kept near the fits only by a weak prior
    assert (t[2] - hill[2]).abs()[visible].max() < 0.03  # R: Hill agrees with Cycles' published R
    assert (t[0] - hill[0]).abs()[visible].max() < 0.1  # A: Cycles' table differs from Hill's by ~0.07


def test_fresnel_moments_reproduce_e() -> None:
    """The hat functions sum to 1, so their albedos sum to E."""
    moments = tables.table("ggx_fresnel_moments", torch.device("cpu"), F64)
    assert torch.allclose(moments.sum(0), tables.table("ggx_E", torch.device("cpu"), F64), atol=1e-9)


# VNDF samples that generating every table evaluates: the rules (QUADRATURE 24, S_QUADRATURE 32)
# the module docstring times at 0.9 s on 2 cores, paid once per process at first use.
VNDF_SAMPLE_BUDGET = 4_063_232


def test_generation_is_deterministic_and_cheap(monkeypatch: pytest.MonkeyPatch) -> None:
    """Cost in quadrature samples, not seconds: a busy machine's seconds measure its neighbours."""
    samples: list[int] = []
    quadrature = tables.vndf_quadrature

    def counting(rough: torch.Tensor, mu: torch.Tensor, n: int = tables.QUADRATURE):
        weight, c, rule = quadrature(rough, mu, n)
        samples.append(rule.numel())
        return weight, c, rule

    monkeypatch.setattr(tables, "vndf_quadrature", counting)
    first = {name: gen() for name, gen in tables._GENERATORS.items()}
    assert 0 < sum(samples) <= VNDF_SAMPLE_BUDGET, f"{sum(samples)} VNDF samples for all tables"
    for name, gen in tables._GENERATORS.items():
        assert torch.equal(first[name], gen()), name
        assert torch.isfinite(first[name]).all(), name
