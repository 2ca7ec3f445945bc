"""train-generator: a tiny run, interrupted and resumed, lands on the uninterrupted run's weights."""
import json

import pytest
import torch
from PIL import Image
from safetensors.torch import load_file

from richmat_addon.core.enhancement_types import TYPES
from torch_models.cli import main
from torch_models.generator import corpus, procedural
from torch_models.generator.train import GeneratorTrainConfig, GeneratorTrainer, learning_rate, load_corpus
from tests.test_generator_text import text_encoder

torch.set_num_threads(1)

TINY = {"model": {"size": 16, "patch": 4, "dim": 32, "depth": 1, "heads": 2},
        "corpus": {"dir": "corpus", "procedural": 3, "views": 2, "resolution": 16, "texture_size": 16},
        "steps": 20, "batch": 2, "warmup": 5, "checkpoint_every": 5, "threads": 1}  # seconds on one thread


@pytest.fixture(scope="module")
def tiny_config(tmp_path_factory):
    root = tmp_path_factory.mktemp("generator")
    path = root / "tiny.json"
    path.write_text(json.dumps(TINY))
    with text_encoder():
        load_corpus(GeneratorTrainConfig.load(path).corpus, progress=False)
    return path


def test_corpus_files_hold_the_documented_tensors(tiny_config):
    files = sorted((tiny_config.parent / "corpus").glob("*.safetensors"))
    assert len(files) == 3
    s = corpus.Sample.load(files[0])
    assert s.target.shape == (2, 6, 16, 16) and s.conditions.shape == (2, 19, 16, 16)
    assert s.unknown_prior.shape == (2, 6, 16, 16)
    assert s.text.shape == (384,) and s.type in range(len(TYPES)) and s.caption.startswith("a ")
    cover = s.conditions[:, -1] > 0
    assert 0 < cover.float().mean() < 1
    assert float(s.target.abs().amax(1)[~cover].max()) == 0.0  # background is empty
    assert float(s.target.abs().amax(1)[cover].min()) > 0.0
    normals = s.conditions[:, 0:3].permute(0, 2, 3, 1)[cover]
    assert torch.allclose(normals.norm(dim=-1), torch.ones(len(normals)), atol=1e-2)
    # roughness, metalness and their known flag: the object's own PBR values inside, 0 outside
    pbr = procedural.make_asset(0, 16, 0).pbr
    roughness, metalness, known = (s.conditions[:, c][cover] for c in (9, 10, 11))
    assert torch.equal(known, torch.ones_like(known)) and float(s.conditions[:, 9:12][~cover[:, None].expand(-1, 3, -1, -1)].abs().max()) == 0
    assert float(roughness.min()) >= float(pbr.roughness.value.min()) - 1e-3
    assert float(roughness.max()) <= float(pbr.roughness.value.max()) + 1e-3
    assert float(metalness.min()) >= float(pbr.metalness.value.min()) - 1e-3
    # the uplift prior: the encoder's latents of the object's PBR material under the named type's
    # rules with fixed draws; a constant-roughness dielectric when the maps are unknown
    for prior in (s.conditions[:, 12:18], s.unknown_prior):
        assert float(prior.abs().amax(1)[~cover].max()) == 0.0 and float(prior.abs().amax(1)[cover].min()) > 0
    assert float((s.target - s.conditions[:, 12:18]).abs().mean()) < float(s.target.abs().mean())


def test_learning_rate_warms_up_then_decays(tiny_config):
    cfg = GeneratorTrainConfig.load(tiny_config)
    rates = [learning_rate(cfg, s) for s in range(cfg.steps)]
    assert rates[0] < rates[4] == pytest.approx(cfg.lr) and rates[-1] < rates[5]


def test_interrupted_and_resumed_run_reproduces_the_uninterrupted_run(tiny_config, tmp_path):
    straight, split = tmp_path / "straight", tmp_path / "split"
    assert main(["train-generator", "--config", str(tiny_config), "--out", str(straight)]) == 0
    assert main(["train-generator", "--config", str(tiny_config), "--out", str(split), "--stop-at", "8"]) == 0
    assert json.loads((split / "state.json").read_text())["step"] == 8  # between checkpoints
    assert main(["train-generator", "--config", str(tiny_config), "--out", str(split)]) == 2  # refuses to overwrite
    assert main(["train-generator", "--config", str(tiny_config), "--out", str(split), "--resume"]) == 0
    a, b = load_file(str(straight / "weights.safetensors")), load_file(str(split / "weights.safetensors"))
    assert a.keys() == b.keys()
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert float(a["net.out.weight"].abs().max()) > 0  # zero-initialised output layer has learned
    state = json.loads((straight / "state.json").read_text())
    assert state["step"] == 20 and [h["step"] for h in state["history"]] == [5, 10, 15, 20]
    assert all(h["loss"] == h["loss"] for h in state["history"])  # finite, not NaN
    with Image.open(straight / "training_curve.png") as im:
        assert im.size[0] > 100


def test_batch_dirs_add_every_asset_of_a_batch_output_index(tmp_path):
    """A batch output folder in ``batch_dirs`` (relative to the config) adds the assets its dataset
    index lists: the complete ones, never an interrupted asset's ``.partial`` work folder."""
    import shutil
    from pathlib import Path

    from batch import index
    from richmat_addon.core.folder_io import FormatError

    asset = Path(__file__).parent / "data" / "generator_batch" / "cone_metal_2"
    out = tmp_path / "batch_out"
    shutil.copytree(asset, out / "cone_metal_2")
    shutil.copytree(asset, out / "cone_metal_3.partial")  # a copy with a manifest, but unfinished
    (out / "_ledger").mkdir()
    cfg_path = tmp_path / "cfg.json"
    cfg_path.write_text(json.dumps({"corpus": {"dir": "corpus", "procedural": 0, "batch_dirs": ["batch_out"]}}))
    cfg = GeneratorTrainConfig.load(cfg_path)
    assert cfg.corpus.batch_dirs == [str(out.resolve())]
    with pytest.raises(FormatError, match="--rebuild-index"):  # an output from before the index
        load_corpus(cfg.corpus, progress=False)
    index.write(out)
    with text_encoder():
        samples = load_corpus(cfg.corpus, progress=False)
    assert [s.asset_id for s in samples] == ["cone_metal_2-a98e222826"]
    # an asset named in ``held_out`` is kept out of training, as the hashed split is
    assert cfg.corpus.trains_on("cone_metal_2-a98e222826")
    cfg.corpus.held_out = ["cone_metal_2-a98e222826"]
    assert not cfg.corpus.trains_on("cone_metal_2-a98e222826") and cfg.corpus.trains_on("cone_metal_3-a98e222826")
    with pytest.raises(ValueError, match="no training objects"):
        GeneratorTrainer(cfg, tmp_path / "run", samples)
