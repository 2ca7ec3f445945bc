"""Training vectors from uplifted real assets: which assets, how many per group, how they are drawn."""
from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np
import pytest
import torch

from richmat_addon.core.enhancement_types import TYPES
from richmat_addon.core.schema import CHANNEL_SLICES
from support.paths import REPO, shared_assets_or_skip
from torch_models.neural import real_vectors
from torch_models.neural.kinds import load_config
from torch_models.neural.data import make_batch

CONFIGS = REPO / "torch_models" / "neural" / "configs"


def evaluated_assets() -> set[str]:
    """Every real asset a bench evaluates on (its module-level ASSETS) or the generator holds out."""
    names: set[str] = set()
    for path in (REPO / "bench").rglob("*.py"):
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "ASSETS" for t in node.targets):
                names |= set(ast.literal_eval(node.value))
    for path in (REPO / "torch_models" / "generator" / "configs").glob("*.json"):
        names |= {a.rsplit("-", 1)[0] for a in json.loads(path.read_text())["corpus"].get("held_out", [])}
    return names


@pytest.mark.parametrize("config", sorted(p.name for p in CONFIGS.glob("*.json")))
def test_no_decoder_trains_on_an_asset_a_bench_evaluates(config):
    cfg = load_config(CONFIGS / config)
    trained_on = {Path(a).stem for a in cfg.real_assets}
    evaluated = evaluated_assets()
    assert {"WaterBottle", "SheenCloth", "BoomBox", "CesiumMilkTruck", "FlightHelmet", "Avocado"} <= evaluated
    assert not trained_on & evaluated
    assert all(Path(a).is_file() for a in cfg.real_assets)


def test_each_asset_and_type_gives_at_most_its_share():
    vectors = real_vectors.build([shared_assets_or_skip() / "models" / "Box.glb"], per_group=5)
    assert len(vectors) == len(TYPES)  # the box's one constant material: one vector per type
    assert vectors.shape[1] == sum(s.stop - s.start for s in CHANNEL_SLICES.values())
    coats = vectors[:, CHANNEL_SLICES["coat_weight"]][:, 0]
    assert (coats > 0).any() and (coats == 0).any()  # the types differ, as enhance makes them


def test_draws_split_between_procedural_and_real_and_favour_metals():
    vectors = np.zeros((10, 22), np.float32)
    vectors[:, CHANNEL_SLICES["alpha_core"]] = 0.3
    vectors[[1, 7], CHANNEL_SLICES["metalness"]] = 1.0  # a procedural metal, a real metal
    vectors[8, CHANNEL_SLICES["alpha_core"]] = 0.001  # a real near-mirror
    w = real_vectors.sampling_weights(vectors, procedural=6, real_share=0.25, emphasis=3.0)
    plain_proc, plain_real = 0.75 / 6, 0.25 / 4
    expected = np.array([plain_proc] * 6 + [plain_real] * 4)
    expected[[1, 7, 8]] *= 3
    np.testing.assert_allclose(w, expected / expected.sum(), rtol=1e-12)
    drawn = make_batch(torch.from_numpy(vectors), 4000, torch.Generator().manual_seed(0),
                       weights=torch.from_numpy(w)).index.numpy()
    share = np.bincount(drawn, minlength=10) / len(drawn)
    np.testing.assert_allclose(share, w, atol=0.02)
