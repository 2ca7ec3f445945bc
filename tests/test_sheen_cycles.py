"""Our sheen against Cycles' sheen closure, measured in a fresh Cycles render.

bench/calibrate_sheen.py fitted the shipped table to such measurements; this
test repeats a small measurement (other sun directions, four roughnesses) so a
change to the lobe, the table or the frame convention shows up as a failure.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from support import sheen_measurement
from torch_models.brdf import lobes, tables


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

    sheen = ~diffuse
    n = data["n"][sheen]
    view = torch.tensor([[0.0, -1.0, 0.0]], dtype=torch.float64).expand(len(n), 3)
    wi, wo = sheen_measurement.to_shading(n, view).float(), sheen_measurement.to_shading(n, data["d"][sheen]).float()
    r = torch.tensor(roughness)[data["sphere"][sheen]][:, None]
    measured = data["value"][sheen].float() / strength
    ours = lobes.sheen_eval(wi, wo, r).squeeze(-1)
    hill = sheen_measurement.model(tables.hill_sheen_ltc(), wi.double(), wo.double(), r.double()).float()
    lit = measured > 1e-3
    err_ours = ((ours - measured).abs()[lit] / measured[lit]).median()
    err_hill = ((hill - measured).abs()[lit] / measured[lit]).median()
    assert err_ours < 0.03, float(err_ours)
    assert err_ours < 0.7 * err_hill  # the calibration is what makes it agree
