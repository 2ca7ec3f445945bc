"""The sheen closure kind (Zeltner LTC): its form, energy, sampler, albedo fit and Cycles' own render of it."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from richmat_addon.core import graph
from richmat_addon.core.closures import sheen
from support import sheen_measurement
from tests.chi2 import sidak_threshold
from tests.closure_support import F64, direction, hemisphere_rule, probe, sampler_chi2, scalar
from torch_models.brdf import lobes, tables


def test_sheen_is_the_ltc_of_wi_and_not_reciprocal() -> None:
    gen = torch.Generator().manual_seed(3)
    v = torch.randn(2, 256, 3, generator=gen, dtype=F64)
    v[..., 2] = v[..., 2].abs() + 0.05
    wi, wo = v / v.norm(dim=-1, keepdim=True)
    r = scalar(0.5)
    a, b, albedo = tables.sheen_ltc(wi[:, 2:3], r)
    t = torch.nn.functional.normalize(torch.cat([wi[:, :2], torch.zeros_like(wi[:, :1])], -1), dim=-1)
    bt = torch.linalg.cross(torch.tensor([0, 0, 1.0], dtype=F64).expand_as(t), t, dim=-1)
    x, y, z = (wo * t).sum(-1, keepdim=True), (wo * bt).sum(-1, keepdim=True), wo[:, 2:3]
    expected = albedo * z * (a / ((a * x + b * z) ** 2 + (a * y) ** 2 + z ** 2)) ** 2 / math.pi
    assert torch.allclose(lobes.sheen_eval(wi, wo, r), expected)
    f_io = lobes.sheen_eval(wi, wo, r) / wo[:, 2:3]
    f_oi = lobes.sheen_eval(wo, wi, r) / wi[:, 2:3]
    assert not torch.allclose(f_io, f_oi, rtol=1e-2)


@pytest.mark.parametrize("r", [0.05, 0.3, 0.6, 1.0])
@pytest.mark.parametrize("mu", [0.02, 0.3, 0.8, 1.0])
def test_sheen_integrates_to_its_albedo(r: float, mu: float) -> None:
    dirs, weights = hemisphere_rule()
    wi = direction(mu, 0.7).expand_as(dirs)
    rr = scalar(r)
    total = float((lobes.sheen_eval(wi, dirs, rr) * weights).sum())
    albedo = float(lobes.sheen_albedo(scalar(mu), rr))
    assert total <= 1.0
    assert total == pytest.approx(albedo, abs=2e-3 * max(albedo, 0.05))
    assert float((lobes.sheen_pdf(wi, dirs, rr) * weights).sum()) == pytest.approx(1.0, abs=2e-3)


SHEEN_CHI2 = [(1.0, 0.5), (0.3, 0.05), (0.6, 0.95), (0.1, 0.3)]


@pytest.mark.parametrize("r,mu", SHEEN_CHI2)
def test_sheen_sampler_chi2(r: float, mu: float) -> None:
    result = sampler_chi2(probe("sheen", {"roughness": r, "color": graph.WHITE}), direction(mu, -1.2), seed=13)
    assert result.passed(sidak_threshold(len(SHEEN_CHI2))), result
    assert result.pdf_integral == pytest.approx(1.0, abs=5e-3)


def test_the_fit_follows_the_torch_table() -> None:
    rng = np.random.default_rng(0)
    mu, rho = rng.uniform(0.1, 1, 400), rng.uniform(0.1, 1, 400)  # the fit's domain
    with torch.no_grad():
        table = lobes.sheen_albedo(torch.from_numpy(mu), torch.from_numpy(rho)).numpy()
    fitted = np.array([sheen.fitted_albedo(m, r) for m, r in zip(mu, rho)])
    assert np.abs(fitted - table).max() <= sheen.ALBEDO_FIT.max_error + 1e-3


# ---- against Cycles' sheen closure, measured in a fresh Cycles render --------------------------------
# bench/material/calibrate_sheen.py fitted the shipped table to such measurements; this repeats a small one (other
# sun directions, four roughnesses), so a change to the lobe, the table or the frame convention fails here.
def _measure(blender_run, folder: Path, roughness: list[float], suns: np.ndarray) -> dict:
    job = folder / "job.json"
    job.write_text(json.dumps({"roughness": roughness, "suns": suns.tolist(), "px_per_unit": 14,
                               "out": str(folder)}))
    blender_run(f"""
        import runpy, sys
        sys.argv = ["sheen_cycles", {str(job)!r}]
        runpy.run_module("support.sheen_cycles", run_name="__main__")
    """)
    import OpenImageIO as oiio

    images = [oiio.ImageBuf(str(folder / f"sun_{k}.exr")).get_pixels(oiio.FLOAT)[..., 0] for k in range(len(suns))]
    return sheen_measurement.samples(images, json.loads((folder / "layout.json").read_text()), suns)


def test_sheen_matches_cycles_measurement(blender_run, tmp_path: Path) -> None:
    roughness = [0.25, 0.5, 0.75, 1.0]
    rng = np.random.default_rng(11)
    suns = rng.normal(size=(3, 3))
    suns[:, 1] = -np.abs(suns[:, 1])  # in front of the spheres
    suns /= np.linalg.norm(suns, axis=1, keepdims=True)
    data = _measure(blender_run, tmp_path, roughness, suns)

    diffuse = data["sphere"] == len(roughness)
    cos_d = (data["n"][diffuse] * data["d"][diffuse]).sum(-1)
    strength = float(torch.median(data["value"][diffuse] * math.pi / cos_d))
    assert strength == pytest.approx(1.0, abs=0.01)  # the measurement itself is calibrated

    lit_by_sheen = ~diffuse
    n = data["n"][lit_by_sheen]
    view = torch.tensor([[0.0, -1.0, 0.0]], dtype=torch.float64).expand(len(n), 3)
    wi = sheen_measurement.to_shading(n, view).float()
    wo = sheen_measurement.to_shading(n, data["d"][lit_by_sheen]).float()
    r = torch.tensor(roughness)[data["sphere"][lit_by_sheen]][:, None]
    measured = data["value"][lit_by_sheen].float() / strength
    ours = lobes.sheen_eval(wi, wo, r).squeeze(-1)
    hill = sheen_measurement.model(tables.hill_sheen_ltc(), wi.double(), wo.double(), r.double()).float()
    lit = measured > 1e-3
    err_ours = ((ours - measured).abs()[lit] / measured[lit]).median()
    err_hill = ((hill - measured).abs()[lit] / measured[lit]).median()
    assert err_ours < 0.03, float(err_ours)
    assert err_ours < 0.7 * err_hill  # the calibration is what makes it agree
