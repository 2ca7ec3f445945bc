"""Measure Cycles' sheen closure and fit our sheen LTC table to it.

Cycles' ``sheen`` reads (A, B, R) from its own tabulation of Zeltner et al.'s
data, which differs from the closed-form fits MaterialX publishes (A by up to
0.07): enough to show as FLIP 0.03 on a dust-covered ball. Rather than copying
Cycles' table, we measure the closure: Cycles renders spheres of the sheen lobe
alone (one per roughness node) under zero-angle suns (support/sheen_cycles.py),
each pixel giving f(wi, wo) cos(theta_o) exactly, and we fit the 32 x 32 x 3
table (initialised from the fits) to those values in log space with Adam.

    python -m bench.material.calibrate_sheen [--out richmat_addon/core/data/sheen_ltc.npy]

Writes the table and docs/reports/sheen_calibration.json (the fit's residual before and
after, per roughness). Takes ~5 minutes on 2 cores.
"""
from __future__ import annotations

import argparse
import json
import math
import tempfile
from pathlib import Path

import numpy as np
import torch

from bench.common import REPO, REPORTS, run_python, write_report
from richmat_addon.core.schema import SHEEN_ROUGHNESS_MIN
from richmat_addon.core.sheen_table import SHEEN_TABLE_FILE
from support.sheen_measurement import model, samples, to_shading
from torch_models.brdf import tables

SUNS = 24
PX_PER_UNIT = 24
STEPS = 800
PRIOR = 1e-3  # weight of the pull towards the starting table


def sun_directions(n: int) -> np.ndarray:
    """A Fibonacci spiral over the directions the camera's hemisphere can see lit (y < 0.6)."""
    k = np.arange(4 * n)
    y = 1 - 2 * (k + 0.5) / (4 * n)
    phi = k * math.pi * (3 - math.sqrt(5))
    r = np.sqrt(1 - y * y)
    d = np.stack([r * np.cos(phi), y, r * np.sin(phi)], -1)
    d = d[d[:, 1] < 0.6]
    return d[np.linspace(0, len(d) - 1, n).round().astype(int)]


def roughness_nodes() -> list[float]:
    return [max(i / (tables.SHEEN_SIZE - 1), SHEEN_ROUGHNESS_MIN) for i in range(tables.SHEEN_SIZE)]


def measure(folder: Path) -> tuple[list[np.ndarray], dict, np.ndarray]:
    suns = sun_directions(SUNS)
    job = folder / "job.json"
    job.write_text(json.dumps({"roughness": roughness_nodes(), "suns": suns.tolist(),
                               "px_per_unit": PX_PER_UNIT, "out": str(folder)}))
    run_python(["-m", "support.sheen_cycles", str(job)], folder)
    return load_measurement(folder)


def load_measurement(folder: Path) -> tuple[list[np.ndarray], dict, np.ndarray]:
    import OpenImageIO as oiio

    suns = np.array(json.loads((folder / "job.json").read_text())["suns"])
    images = [oiio.ImageBuf(str(folder / f"sun_{k}.exr")).get_pixels(oiio.FLOAT)[..., 0]
              for k in range(len(suns))]
    return images, json.loads((folder / "layout.json").read_text()), suns


def fit(start: torch.Tensor, loss_of) -> torch.Tensor:  # type: ignore[no-untyped-def]
    """Adam on (log A, B, log R): A and R span four decades and must stay positive.

    A weak pull towards the starting table keeps cells no pixel constrains
    (mu < 0.2, where the fits agree with Cycles' published R within 0.01) where
    the fits put them; a weak curvature penalty along mu keeps rows smooth.
    """
    log_a = start[0].clamp(min=1e-6).log().clone().requires_grad_(True)
    b = start[1].clone().requires_grad_(True)
    log_r = start[2].clamp(min=1e-6).log().clone().requires_grad_(True)
    opt = torch.optim.Adam([log_a, b, log_r], lr=1e-2)
    init = [p.detach().clone() for p in (log_a, b, log_r)]
    for step in range(STEPS):
        opt.zero_grad()
        table = torch.stack([log_a.exp(), b, log_r.exp()])
        prior = sum(((p - p0) ** 2).mean() + (p[:, 2:] - 2 * p[:, 1:-1] + p[:, :-2]).pow(2).mean()
                    for p, p0 in zip((log_a, b, log_r), init))
        loss = loss_of(table).mean() + PRIOR * prior
        loss.backward()
        opt.step()
        if step % 250 == 0:
            print(f"step {step}: loss {loss.item():.4f}", flush=True)
    return torch.stack([log_a.exp(), b, log_r.exp()]).detach()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=SHEEN_TABLE_FILE)
    parser.add_argument("--report", type=Path, default=REPORTS / "sheen_calibration.json")
    parser.add_argument("--measurements", type=Path, default=None,
                        help="keep the Cycles measurement in this folder, or reuse the one already there")
    args = parser.parse_args()
    if args.measurements and (args.measurements / "layout.json").exists():
        images, layout, suns = load_measurement(args.measurements)
    elif args.measurements:
        args.measurements.mkdir(parents=True, exist_ok=True)
        images, layout, suns = measure(args.measurements)
    else:
        with tempfile.TemporaryDirectory(prefix="richmat_sheen_") as tmp:
            images, layout, suns = measure(Path(tmp))
    data = samples(images, layout, suns)
    n_spheres = len(layout["centres_px"])
    diffuse = data["sphere"] == n_spheres - 1
    cos_d = (data["n"][diffuse] * data["d"][diffuse]).sum(-1)
    strength = float(torch.median(data["value"][diffuse] * math.pi / cos_d))
    print(f"sun strength seen on the white Lambertian: {strength:.4f} (expected 1)")
    sheen = ~diffuse
    wi = to_shading(data["n"][sheen], torch.tensor([[0.0, -1.0, 0.0]], dtype=torch.float64).expand(int(sheen.sum()), 3))
    wo = to_shading(data["n"][sheen], data["d"][sheen])
    r = torch.tensor(roughness_nodes(), dtype=torch.float64)[data["sphere"][sheen]][:, None]
    target = data["value"][sheen] / strength
    floor = 1e-4

    def loss_of(table: torch.Tensor) -> torch.Tensor:
        return (torch.log(model(table, wi, wo, r).clamp(min=0.0) + floor) - torch.log(target + floor)).abs()

    start = tables.hill_sheen_ltc().clone()
    fitted = fit(start, loss_of)
    with torch.no_grad():
        before, after = loss_of(start), loss_of(fitted)
    sphere = data["sphere"][sheen]
    per_r = [{"roughness": rr, "before": float(before[sphere == j].mean()), "after": float(after[sphere == j].mean())}
             for j, rr in enumerate(roughness_nodes())]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    np.save(args.out, fitted.numpy().astype(np.float32))
    report = {"samples": int(sheen.sum()), "suns": SUNS, "sun_strength_measured": strength,
              "mean_abs_log_error_before": float(before.mean()), "mean_abs_log_error_after": float(after.mean()),
              "max_change": {k: float((fitted[j] - start[j]).abs().max()) for j, k in enumerate("ABR")},
              "per_roughness": per_r}
    write_report(args.report, report)
    print(f"mean |log error| {report['mean_abs_log_error_before']:.4f} -> {report['mean_abs_log_error_after']:.4f}; "
          f"wrote {args.out}")


if __name__ == "__main__":
    main()
