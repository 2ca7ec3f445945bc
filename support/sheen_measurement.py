"""Reading a Cycles sheen measurement (``support/sheen_cycles.py``'s renders) back as samples of f cos, and
our sheen lobe with its LTC table as a free parameter: what bench/material/calibrate_sheen.py fits the shipped table
with and tests/test_closure_sheen.py checks it against."""
from __future__ import annotations

import numpy as np
import torch

from torch_models.brdf import lobes, tables
from torch_models.brdf.frame import tangent_frame, to_local

MU_MIN = 0.2  # grazing limit of trusted pixels (see samples())


def samples(images: list[np.ndarray], layout: dict, suns: np.ndarray) -> dict[str, torch.Tensor]:
    """Per lit pixel of every sphere: normal, sun direction, sphere index, measured f cos."""
    h, w = images[0].shape
    ys, xs = np.mgrid[0:h, 0:w] + 0.5
    rad = layout["radius_px"]
    rows = []
    for s, (cx, cy) in enumerate(layout["centres_px"]):
        ox, oz = (xs - cx) / rad, -(ys - cy) / rad
        # mu >= 0.2 only: on the white Lambertian sphere, pixels seen more grazingly than that
        # differ from cos/pi by 10-30 % (silhouette sampling), above it by 1 % (median).
        inside = ox ** 2 + oz ** 2 < 1.0 - MU_MIN ** 2
        n = np.stack([ox[inside], -np.sqrt(1 - ox[inside] ** 2 - oz[inside] ** 2), oz[inside]], -1)
        for k, d in enumerate(suns):
            rows.append((n, np.broadcast_to(d, n.shape), np.full(len(n), s), images[k][inside]))
    n, d, sphere, value = (np.concatenate(c) for c in zip(*rows))
    keep = (n @ np.array([0, -1.0, 0]) > 0) & ((n * d).sum(-1) > 0.02)
    t = lambda a, dt=torch.float64: torch.from_numpy(np.ascontiguousarray(a[keep])).to(dt)  # noqa: E731
    return {"n": t(n), "d": t(d), "sphere": t(sphere, torch.long), "value": t(value)}


def to_shading(n: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """v in a frame whose z is n (any tangent; the sheen frame is applied later)."""
    helper = torch.where(n[:, 2:3].abs() < 0.9, torch.tensor([0.0, 0, 1], dtype=n.dtype),
                         torch.tensor([1.0, 0, 0], dtype=n.dtype))
    t = torch.nn.functional.normalize(torch.cross(helper, n, dim=-1), dim=-1)
    b = torch.cross(n, t, dim=-1)
    return torch.stack([(v * t).sum(-1), (v * b).sum(-1), (v * n).sum(-1)], -1)


def model(table: torch.Tensor, wi: torch.Tensor, wo: torch.Tensor, r: torch.Tensor) -> torch.Tensor:
    """R * LTC density, as lobes.sheen_eval, with the table as a free parameter."""
    mu = wi[:, 2:3]
    a, b, albedo = (tables.lookup(table[j], mu, r) for j in range(3))
    frame = tangent_frame(wi)
    return (albedo * lobes._ltc_density(to_local(wo, *frame), a, b)).squeeze(-1)
