"""Training vectors from uplifted real materials, beside the procedural ones (issue 41, item 4).

The procedural pool (``data.parameter_vectors``) enhances constant PBR inputs; what users
bring are textured materials whose maps mix metal and dielectric, sharp and rough, in the
proportions real assets have. Each asset a training config names is enhanced as the farm
does (``enhance``, every enhancement type, dielectric-only types remapped on metals), its
texel vectors deduplicated at the fit's cluster step, and an equal share of vectors kept
per (asset, type), so that no single 1k texture outweighs the rest.

Assets that a benchmark evaluates on must stay out of training; the config names its
assets explicitly and tests/test_real_vectors.py checks them against every bench's list.
"""
from __future__ import annotations

import argparse
import hashlib
import tempfile
from pathlib import Path

import numpy as np

from richmat_addon.core.enhancement_types import TYPES
from richmat_addon.core.schema import CHANNEL_SLICES
from richmat_addon.core.texel_vectors import read_vectors

MIRROR_ALPHA = 0.02  # a core GGX alpha below this is a near-mirror (roughness under ~0.14)


def enhanced_folders(asset: Path, out: Path, type_: int | str = "auto", seed: int = 0) -> list[Path]:
    """The material folders of ``asset`` enhanced as the farm does (``enhance``; ``type_`` a type index or
    "auto"; dielectric-only types remapped on metals), written into ``out``."""
    from ..cli_enhance import run

    run(argparse.Namespace(asset=asset, type=str(type_), seed=seed, out=out, on_metal="remap"))
    return [folder for folder in sorted(out.iterdir()) if (folder / "params.json").exists()]


def uplift(asset: Path, type_: int, seed: int, out: Path) -> list[np.ndarray]:
    """The deduplicated texel vectors of each material of ``asset`` enhanced at ``type_``."""
    return [read_vectors(folder).unique for folder in enhanced_folders(asset, out, type_, seed)]


def build(assets: list[Path], per_group: int, seed: int = 0) -> np.ndarray:
    """(N, 22) vectors: at most ``per_group`` of each (asset, type) group's unique texel vectors,
    drawn without replacement."""
    rng = np.random.default_rng(seed)
    groups = []
    with tempfile.TemporaryDirectory() as tmp:
        for asset in assets:
            for t in TYPES:
                rows = np.concatenate(uplift(asset, t.index, seed, Path(tmp) / f"{asset.stem}_{t.index}"))
                keep = rng.choice(len(rows), min(per_group, len(rows)), replace=False)
                groups.append(rows[np.sort(keep)])
    return np.concatenate(groups).astype(np.float32)


def load_or_build(assets: list[Path], per_group: int, cache: Path) -> np.ndarray:
    """``build``'s vectors, kept in ``cache`` (keyed by the assets' bytes and ``per_group``)."""
    key = hashlib.sha256(str(per_group).encode())
    for asset in assets:
        key.update(asset.name.encode() + hashlib.sha256(asset.read_bytes()).digest())
    if cache.exists():
        with np.load(cache) as f:
            if str(f["key"]) == key.hexdigest():
                return f["vectors"]
    vectors = build(assets, per_group)
    cache.parent.mkdir(parents=True, exist_ok=True)
    np.savez(cache, vectors=vectors, key=key.hexdigest())
    return vectors


def emphasised(vectors: np.ndarray) -> np.ndarray:
    """(N,) True where a vector is a metal or a near-mirror: what the shipped decoder draws worst."""
    metal = vectors[:, CHANNEL_SLICES["metalness"]][:, 0] > 0.5
    mirror = vectors[:, CHANNEL_SLICES["alpha_core"]][:, 0] < MIRROR_ALPHA
    return metal | mirror


def sampling_weights(vectors: np.ndarray, procedural: int, real_share: float, emphasis: float) -> np.ndarray:
    """(N,) probabilities of drawing each pool row: the first ``procedural`` rows share
    1 - ``real_share``, the rest ``real_share``; metals and near-mirrors count ``emphasis`` times."""
    n_real = len(vectors) - procedural
    w = np.where(np.arange(len(vectors)) < procedural, (1 - real_share) / max(procedural, 1),
                 real_share / max(n_real, 1))
    w = w * np.where(emphasised(vectors), emphasis, 1.0)
    return w / w.sum()
