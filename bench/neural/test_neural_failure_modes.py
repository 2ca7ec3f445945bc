"""The sweeps of bench/neural/neural_failure_modes.py move one parameter, monotonically, and nothing else
(a bench's own test, collected by ``make test`` beside tests/)."""
from __future__ import annotations

import numpy as np

from bench.neural.neural_failure_modes import QUICK, sweeps
from richmat_addon.core.schema import CHANNEL_SLICES


def _channel(points: list, name: str) -> np.ndarray:
    return np.array([p.vector[CHANNEL_SLICES[name]][0] for p in points])


def test_sweeps_are_monotone_in_the_swept_parameter_only() -> None:
    points = sweeps(3, QUICK)
    by = {name: [p for p in points if p.sweep == name] for name in {p.sweep for p in points}}
    assert {len(v) for v in by.values()} == {3, 4}
    for kind in ("dielectric", "metal"):
        rough = by[f"roughness, {kind}"]
        for name in ("alpha_core", "alpha_haze"):
            assert np.all(np.diff(_channel(rough, name)) >= 0) and _channel(rough, name)[-1] > _channel(rough, name)[0]
        # The enhancement's own draws (haze weight, IOR, edge tint) do not move with roughness.
        for name in ("haze_weight", "diel_ior", "edge_tint", "metalness"):
            assert np.ptp(_channel(rough, name)) == 0
    assert np.all(_channel(by["roughness, metal"], "metalness") == 1.0)
    assert np.allclose(_channel(by["metalness"], "metalness"), QUICK["metalness"])
    assert np.allclose(_channel(by["ior"], "diel_ior"), QUICK["ior"])
    ior = np.stack([p.vector for p in by["ior"]])
    others = np.ones(ior.shape[1], bool)
    others[CHANNEL_SLICES["diel_ior"]] = False
    assert np.ptp(ior[:, others], axis=0).max() == 0
