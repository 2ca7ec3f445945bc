"""The add-on's numpy encoder (core/neural_encoder.py) against torch's, and the encoder-only fit."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from richmat_addon.core import material_folder, neural_folder
from richmat_addon.core.enhance import enhance
from richmat_addon.core.folder_io import read_exr
from richmat_addon.core.neural_encoder import GGX_ALPHAS, Encoder, encode_material
from richmat_addon.core.schema import bounds
from richmat_addon.core.texel_vectors import read_vectors
from torch_models.demo_material import chipped_paint, sphere_texel_geometry
from torch_models.neural import data, trained
from torch_models.neural.fit import material_vectors
from torch_models.neural.fit.latents import fitting_pool

SHIPPED = trained.SHIPPED


def random_vectors(n: int, seed: int = 0) -> np.ndarray:
    """Packed vectors across the schema's ranges and a little beyond (the encoder takes any)."""
    lo, hi = (np.asarray(b, np.float32) for b in bounds())
    u = np.random.default_rng(seed).uniform(-0.1, 1.1, (n, len(lo))).astype(np.float32)
    return lo + u * (hi - lo)


def test_numpy_encoder_equals_torch_encoder_on_random_vectors() -> None:
    model = trained.load(SHIPPED)
    encoder = Encoder.load(SHIPPED)
    vectors = random_vectors(4096)
    with torch.no_grad():
        expected = model.encoder(torch.from_numpy(vectors)).numpy()
    np.testing.assert_allclose(encoder(vectors), expected, rtol=0, atol=1e-5)
    assert encoder.decoder_sha256 == model.digest and encoder.alpha_floor == model.alpha_floor > 0


def test_floor_and_alphas_follow_the_torch_fit() -> None:
    assert set(GGX_ALPHAS) == set(data.GGX_ALPHAS)
    model, encoder = trained.load(SHIPPED), Encoder.load(SHIPPED)
    vectors = random_vectors(512, seed=1)
    np.testing.assert_array_equal(encoder.floored(vectors), fitting_pool(model, vectors).numpy())


def test_encoder_only_fit_writes_the_encoder_latents_deduplicated_as_torch_does(tmp_path: Path) -> None:
    pbr = chipped_paint(16)
    normals, positions = sphere_texel_geometry(16, 16)
    material = tmp_path / "mat"
    material_folder.write(material, enhance(pbr, 1, 3, normals, positions), {"asset": "test"})
    ours, theirs = read_vectors(material), material_vectors.read_vectors(material)
    assert ours.shape == theirs.shape == (16, 16) and ours.exact_unique == theirs.exact_unique
    np.testing.assert_array_equal(ours.unique, theirs.unique)
    np.testing.assert_array_equal(ours.inverse, theirs.inverse)

    record = encode_material(material, tmp_path / "neural", SHIPPED)
    folder = neural_folder.read(tmp_path / "neural")
    assert record == folder.record and record["encoder_only"] is True and record["steps"] == 0
    assert record["fitted_vectors"] == len(ours.unique) < record["texels"] == 256
    assert folder.decoder_sha256 == trained.digest(SHIPPED) and folder.energy_scale == 1.0
    model = trained.load(SHIPPED)
    with torch.no_grad():
        expected = theirs.texels(model.encoder(fitting_pool(model, theirs.unique)))
    latents = np.concatenate([read_exr(p) for p in folder.latent_paths], -1)
    np.testing.assert_allclose(latents, expected, rtol=0, atol=1e-3)  # half-float EXRs
