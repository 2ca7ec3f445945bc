"""The dataset index: written at the end of every run, rebuilt from the manifests alone, read by the
torch loader, refused with the field named when it is foreign, old or names files that are gone."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from torch.utils.data import DataLoader

from batch import index, publish
from batch.orchestrator import main, run
from batch.pipeline import Commands
from richmat_addon.core import neural_folder
from richmat_addon.core.folder_io import FormatError
from tests.test_batch_orchestrator import args_for, decoder, fakes, make_assets  # noqa: F401 (fixtures)
from torch_models.assets import dataset_index
from torch_models.dataset import BatchDataset

DATA = Path(__file__).parent / "data" / "generator_batch"
TEXTURED = np.linspace(-1, 1, 4 * 4 * 6, dtype=np.float32).reshape(4, 4, 6)
CONSTANT = np.arange(6, dtype=np.float32) / 10


def tiny_output(out: Path) -> None:
    """Two assets published as batch publishes them, with the format modules' files: one with a
    textured material, one with a constant one; two frames each (the intrinsics are the fixture's)."""
    for name, latents in (("tex", TEXTURED), ("const", CONSTANT)):
        work = publish.fresh_partial(out, name)
        neural_folder.write(work / "materials" / "m" / "neural", latents, np.ones(latents.shape[:-1]), "digest", {})
        (work / "rgb").mkdir()
        (work / "passes").mkdir()
        for i in range(2):
            Image.new("RGB", (8, 8), (40 * i, 0, 0)).save(work / "rgb" / f"{i:04d}.png")
            shutil.copy(DATA / "cone_metal_2" / "passes" / f"{i:04d}.exr", work / "passes")
        (work / "cameras.json").write_text(json.dumps({"frames": [{"frame": 0}, {"frame": 1}]}))
        frames = [{"frame": i, "beauty": f"rgb/{i:04d}.png", "intrinsics": f"passes/{i:04d}.exr"} for i in range(2)]
        publish.publish(out, name, {"asset_id": name, "source": f"{name}.glb", "caption": f"a {name}",
                                    "enhancement_type": 2, "frames": frames, "settings_hash": "h",
                                    "materials": [{"name": "M", "folder": "m", "type": 2, "settings": {"p": 1.5}}]})
    index.write(out)


def test_every_run_writes_the_index_of_all_published_assets(tmp_path: Path, fakes: Commands,  # noqa: F811
                                                            decoder: Path) -> None:  # noqa: F811
    inp = make_assets(tmp_path / "in", [f"a{i}.glb" for i in range(6)])
    out = tmp_path / "out"
    for shard in ("0/2", "1/2"):  # two shards into one output: each run's index covers both
        assert run(args_for(inp, out, decoder, "--shard", shard), fakes) == 0
        published = sorted(p.name for p in out.iterdir() if (p / "manifest.json").is_file())
        assert [r["asset_id"] for r in dataset_index.read(out).records] == published
    assert len(published) == 6
    record = dataset_index.read(out).records[0]
    manifest = publish.read_manifest(out / record["asset_id"])
    assert record["caption"] == manifest["caption"] and record["settings_hash"] == manifest["settings_hash"]

    shutil.copytree(out / published[0], out / "unfinished.partial")  # its manifest is written, not renamed
    written = (out / dataset_index.INDEX).read_bytes()
    (out / dataset_index.INDEX).unlink()
    assert main(["--rebuild-index", str(out)]) == 0
    assert (out / dataset_index.INDEX).read_bytes() == written


def test_the_fixture_index_is_what_a_rebuild_from_its_manifest_gives() -> None:
    assert index.published_records(DATA) == dataset_index.read(DATA).records


def test_an_asset_published_while_the_index_is_written_gets_into_it(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """Another shard publishing between this writer's listing and its rename must not be lost."""
    out = tmp_path / "out"
    shutil.copytree(DATA / "cone_metal_2", out / "first")
    plain_write = dataset_index.write

    def write_while_another_shard_publishes(path: Path, records: list[dict]) -> None:
        plain_write(path, records)
        if not (out / "second").exists():
            shutil.copytree(DATA / "cone_metal_2", out / "second")

    monkeypatch.setattr(dataset_index, "write", write_while_another_shard_publishes)
    index.write(out)
    assert [r["cameras"] for r in dataset_index.read(out).records] == ["first/cameras.json", "second/cameras.json"]


def test_the_loader_gives_each_record_with_the_arrays_it_asks_for(tmp_path: Path) -> None:
    tiny_output(tmp_path)
    assets = BatchDataset(tmp_path, load=dataset_index.KINDS)
    assert len(assets) == 2
    const, tex = assets[0], assets[1]
    assert const["record"]["asset_id"] == "const" and tex["record"]["caption"] == "a tex"
    assert tex["record"]["materials"][0]["parameters"] == {"p": 1.5}
    assert np.array_equal(const["latents"][0], CONSTANT)
    assert np.allclose(tex["latents"][0], TEXTURED, atol=1e-3)  # half-float EXRs
    assert tex["frames"].shape == (2, 8, 8, 3) and tex["frames"].dtype == np.uint8 and tex["frames"][1, 0, 0, 0] == 40
    assert {"Normal", "Position", "basecolor", "coverage", "latent_a", "latent_b"} <= tex["intrinsics"].keys()
    assert tex["intrinsics"]["coverage"].shape[:3] == (2, 32, 32)
    assert len(tex["cameras"]["frames"]) == 2
    assert BatchDataset(tmp_path)[0].keys() == {"record"}  # nothing is read that was not asked for
    batches = list(DataLoader(BatchDataset(tmp_path, load=("frames",)), batch_size=None))
    assert [tuple(b["frames"].shape) for b in batches] == [(2, 8, 8, 3)] * 2


def test_missing_files_are_named_with_their_asset(tmp_path: Path) -> None:
    tiny_output(tmp_path)
    (tmp_path / "tex" / "passes" / "0001.exr").unlink()
    BatchDataset(tmp_path, load=("frames", "latents"))  # what is not asked for is not checked
    with pytest.raises(FileNotFoundError, match=r"1 of 2 assets lack files \(intrinsics\): tex: tex/passes/0001.exr"):
        BatchDataset(tmp_path, load=("intrinsics",))
    with pytest.raises(ValueError, match="unknown kinds"):
        BatchDataset(tmp_path, load=("beauty",))


@pytest.mark.parametrize("change, message", [
    (lambda r: {"asset": r["asset_id"]}, "line 2: no 'format' field; written by an older richmat or another program"),
    (lambda r: {**r, "format": 0}, "line 2: format is 0, this richmat reads 1: rebuild it with"),
    (lambda r: {k: v for k, v in r.items() if k != "caption"}, "line 2: no 'caption' field"),
    (lambda r: {**r, "materials": [{"name": "M"}]}, r"line 2: no materials\[0\].type, .*materials\[0\].latents field"),
])
def test_a_foreign_or_old_index_is_refused_naming_the_field(tmp_path: Path, change, message: str) -> None:
    tiny_output(tmp_path)
    path = tmp_path / dataset_index.INDEX
    first, second = path.read_text().splitlines()
    path.write_text(first + "\n" + json.dumps(change(json.loads(second))) + "\n")
    with pytest.raises(FormatError, match=message):
        dataset_index.read(tmp_path)


def test_an_output_without_index_says_how_to_make_one(tmp_path: Path) -> None:
    with pytest.raises(FormatError, match=f"no _index.jsonl.*--rebuild-index {tmp_path}"):
        BatchDataset(tmp_path)
