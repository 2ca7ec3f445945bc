"""The generator benches' held-out real assets: read as ``generate`` reads a file, batch's fitted
latents as references, and uplifts that batch would caption the same way."""
import shutil
from pathlib import Path

import numpy as np
import pytest

from richmat_addon.core import neural_folder
from richmat_addon.core.folder_io import read_exr
from support.held_out_assets import real_held_out
from torch_models.generator.train import GeneratorTrainConfig

DATA = Path(__file__).parent / "data" / "generator_batch"
ASSET = "cone_metal_2-a98e222826"


@pytest.fixture(scope="module")
def batch(tmp_path_factory) -> Path:
    """The test batch output with the neural.json its subset leaves out, written as batch writes it."""
    out = tmp_path_factory.mktemp("batch") / "out"
    shutil.copytree(DATA, out)
    neural = out / "cone_metal_2" / "materials" / "metal" / "neural"
    latents = np.concatenate([read_exr(neural / f"latent_{k}.exr") for k in (0, 1)], -1)
    neural_folder.write(neural, latents, np.ones(latents.shape[:2], np.float32), "0" * 64, {"material": ".."})
    return out


def config(batch: Path, held_out: list[str]) -> GeneratorTrainConfig:
    cfg = GeneratorTrainConfig()
    cfg.corpus.batch_dirs, cfg.corpus.held_out = [str(batch)], held_out
    return cfg


def test_a_held_out_asset_carries_batchs_caption_and_fitted_latents(batch):
    [obj] = real_held_out(config(batch, [ASSET]), models=batch)
    assert obj.asset_id == ASSET and obj.type == 1
    assert obj.prompt == "a cone metal 2: white metal with heavy haze, light dust"
    assert [m.name for m in obj.inp.materials] == ["metal"]
    neural = DATA / "cone_metal_2" / "materials" / "metal" / "neural"
    fitted = np.concatenate([read_exr(neural / f"latent_{k}.exr") for k in (0, 1)], -1)
    assert np.array_equal(obj.reference(16)[0], fitted)
    [plain] = obj.plain_pbr(16)
    assert plain.shape == (*obj.shapes(16)[0], 6) and np.abs(plain).max() <= 1.0
    assert not np.allclose(plain, plain.reshape(-1, 6).mean(0))  # the maps' texture, not a constant


def test_the_uplift_with_batchs_type_and_draws_is_captioned_as_batch_captioned_it(batch):
    [obj] = real_held_out(config(batch, [ASSET]), models=batch)
    latents, caption = obj.uplifted(obj.type, 16)
    assert caption == obj.prompt
    other = obj.uplifted(2, 16)
    assert other[1] != caption and "clearcoat" in other[1]
    assert np.abs(other[0][0] - latents[0]).mean() > 0.01


def test_an_asset_missing_from_the_batch_outputs_or_none_held_out_is_refused(batch):
    with pytest.raises(SystemExit, match="in none of the batch outputs"):
        real_held_out(config(batch, [ASSET, "Teapot-0000000000"]), models=batch)
    with pytest.raises(SystemExit, match="holds no real asset out"):
        real_held_out(config(batch, []), models=batch)
