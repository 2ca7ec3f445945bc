"""End to end with real Blender and torch: a tiny batch over good and deliberately broken assets.

One run (2 frames, 32 px, 2 samples, 2 fit steps) over: an OBJ with a
unicode name, a texture far over --max-texture and a missing roughness
texture; an STL without UVs; a .blend whose driver and registered text block
would write marker files if they ever ran; a truncated GLB; an ASCII FBX; an
OBJ with no faces; an unsupported format. Good assets must be rendered with
every output, bad ones reported in the ledger with a reason, and nothing may
stop the batch. Renders with the shipped decoder, or ``$RICHMAT_DECODER`` when set;
a decoder folder without its weights fails the test.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from PIL import Image

from batch import ledger
from batch.options import DEFAULT_DECODER, DEFAULT_DENOISE_PREFILTER, DEFAULT_DENOISE_QUALITY
from richmat_addon.core import neural_folder
from richmat_addon.core.enhancement_types import TYPES
from support.batch_inputs import TETRA_STL, make_inputs
from torch_models.assets import dataset_index
from torch_models.dataset import BatchDataset

REPO = Path(__file__).resolve().parents[1]


def decoder_folder() -> Path:
    folder = Path(os.environ.get("RICHMAT_DECODER", DEFAULT_DECODER))
    missing = [name for name in ("weights.safetensors", "state.json") if not (folder / name).is_file()]
    assert not missing, f"the decoder folder {folder} lacks {missing} (the shipped one is {DEFAULT_DECODER})"
    return folder


def test_tiny_batch_renders_good_assets_and_reports_bad_ones(tmp_path: Path) -> None:
    decoder = decoder_folder()
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "blender_user"), PYTHONPATH=str(REPO))
    marker = tmp_path / "autoexec_ran"
    inputs, out = tmp_path / "in", tmp_path / "out"
    make_inputs(inputs, marker, env)
    cmd = [sys.executable, str(REPO / "batch" / "render_dataset.py"), "--input", str(inputs), "--output",
           str(out), "--frames", "2", "--resolution", "32", "--samples", "2", "--aov-samples", "1",
           "--fit-steps", "2", "--max-texture", "16", "--decoder", str(decoder), "--timeout", "300",
           "--retries", "0"]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 1, proc.stderr[-3000:]  # some assets failed, the batch finished
    records = {r["source"]: r for path in (out / "_ledger").glob("*.jsonl") for r in ledger.read(path)}
    failed = {k: r["reason"] for k, r in records.items() if r["status"] == "failed"}
    assert set(failed) == {"truncated.glb", "ascii.fbx", "zero_faces.obj", "points.xyz"}, records
    assert "ASCII FBX" in failed["ascii.fbx"]
    assert "no mesh" in failed["zero_faces.obj"] or "zero faces" in failed["zero_faces.obj"]
    assert "unsupported format '.xyz'" in failed["points.xyz"]
    assert failed["truncated.glb"].startswith("prepare: ")

    done = {k for k, r in records.items() if r["status"] == "done"}
    assert done == {"painted cube ünï.obj", "no_uvs.stl", "trap.blend"}
    notes = records["painted cube ünï.obj"]["notes"]
    assert any("downscaled from 1024x1024 to 16x16" in n for n in notes), notes
    assert any("is missing" in n and "gone.png" in n and "socket value used" in n for n in notes), notes
    assert any("unwrapped with xatlas" in n for n in records["no_uvs.stl"]["notes"])
    assert not list(tmp_path.glob("autoexec_ran*"))  # neither the driver nor the text block ran

    for source in done:
        folder = next(p for p in out.iterdir() if p.name.startswith(Path(source).stem[:6]) and
                      (p / "manifest.json").is_file())
        manifest = json.loads((folder / "manifest.json").read_text())
        for name in ("rgb/0000.png", "rgb/0001.png", "passes/0000.exr", "passes/0001.exr", "orbit.mp4",
                     "cameras.json", "caption.txt"):
            assert name in manifest["files"], (source, name)
        assert manifest["enhancement_type"] in range(len(TYPES)) and manifest["caption"].startswith("a ")
        assert manifest["cycles"] == {"device": "CPU", "shading_system": "svm", "samples": 2,  # what reached Cycles
                                      "adaptive_threshold": 0.01, "denoiser": "OPENIMAGEDENOISE",
                                      "denoising_prefilter": DEFAULT_DENOISE_PREFILTER.upper(),
                                      "denoising_quality": DEFAULT_DENOISE_QUALITY.upper(), "max_bounces": 3}
        assert all(m["furnace"]["checked"] > 0 for m in manifest["fit"]["materials"].values())
        if source == "trap.blend":
            assert manifest["autoexec_fail"] is True
        cams = json.loads((folder / "cameras.json").read_text())
        assert len(cams["frames"]) == 2 and cams["intrinsics"]["width"] == 32
        assert mp4_frame_size(folder / "orbit.mp4") == (32, 32)
        beauty = np.asarray(Image.open(folder / "rgb" / "0000.png"))
        assert beauty.shape == (32, 32, 3) and beauty.max() > 20 and beauty[0, 0].max() == 0  # black background
        for frame in cams["frames"]:  # every frame's maps are seen from that frame's camera
            frame_layers = check_intrinsics(folder / "passes" / f"{frame['frame']:04d}.exr")
            assert np.percentile(reprojection_px(frame_layers, cams["intrinsics"], frame), 95) < 0.25, source
        layers = check_intrinsics(folder / "passes" / "0000.exr")
        if source == "trap.blend":  # one constant material: its fitted latent, negative values included
            neural = neural_folder.read(next(folder.glob("materials/*/neural"))).record
            covered = layers["coverage"][..., 0] > 0.99
            seen = np.concatenate([np.median(layers[n][covered][:, :3], axis=0) for n in ("latent_a", "latent_b")])
            assert np.allclose(seen, neural["latent"], atol=2e-3)
    assert not list(out.glob("*.partial"))
    assets = BatchDataset(out, load=dataset_index.KINDS)  # the run's index names every file it loads
    assert sorted(a["record"]["source"] for a in assets) == sorted(done)


def mp4_frame_size(path: Path) -> tuple[int, int]:
    """Width and height of an MP4's video track: the last two 16.16 fixed-point fields of its ``tkhd`` box."""
    data = path.read_bytes()
    at = data.index(b"tkhd") - 4
    box = data[at:at + int.from_bytes(data[at:at + 4], "big")]
    return int.from_bytes(box[-8:-4], "big") >> 16, int.from_bytes(box[-4:], "big") >> 16


def reprojection_px(layers: dict[str, np.ndarray], intrinsics: dict, frame: dict) -> np.ndarray:
    """Pixel distance between each covered pixel's centre and its ``Position`` seen through ``frame``'s camera."""
    rows, cols = np.nonzero(layers["coverage"][..., 0] > 0.99)
    world = np.concatenate([layers["Position"][rows, cols, :3], np.ones((len(rows), 1))], axis=1)
    x, y, z = (world @ np.array(frame["world_to_camera"]).T)[:, :3].T  # the camera looks down -Z, +Y up
    u = intrinsics["cx"] + intrinsics["fx"] * x / -z
    v = intrinsics["cy"] - intrinsics["fy"] * y / -z  # image rows go down
    return np.hypot(u - (cols + 0.5), v - (rows + 0.5))


def check_intrinsics(path: Path) -> dict[str, np.ndarray]:
    import OpenImageIO as oiio

    image = oiio.ImageInput.open(str(path))
    layers = {}
    index = 0
    while image.seek_subimage(index, 0):
        spec = image.spec()
        layers[spec.channelnames[0].split(".")[0]] = image.read_image(format=oiio.FLOAT)
        index += 1
    image.close()
    assert set(layers) == {"Normal", "Position", "basecolor", "latent_a", "latent_b", "coverage"}
    covered = layers["coverage"][..., 0] > 0.99
    assert 0.05 < covered.mean() < 0.95
    normals = layers["Normal"][covered]
    assert np.allclose(np.linalg.norm(normals, axis=-1), 1.0, atol=0.05)
    assert np.abs(layers["Position"][covered]).max() <= 0.51  # normalised to the unit cube
    assert layers["basecolor"][covered][:, :3].max() > 0.01
    for name in ("latent_a", "latent_b"):
        assert np.abs(layers[name][covered][:, :3]).max() > 0 and np.abs(layers[name][~covered]).max() == 0
    return layers


def test_a_missing_gpu_fails_the_run_at_once_with_the_reason_in_the_ledger(tmp_path: Path) -> None:
    # a GPU this machine does not have: CUDA on a machine without NVIDIA's driver, else AMD's HIP
    device = "HIP" if Path("/dev/nvidiactl").exists() else "CUDA"
    inputs, out = tmp_path / "in", tmp_path / "out"
    inputs.mkdir()
    (inputs / "cube.stl").write_text(TETRA_STL)
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "blender_user"), PYTHONPATH=str(REPO))
    proc = subprocess.run([sys.executable, str(REPO / "batch" / "render_dataset.py"), "--input", str(inputs),
                           "--output", str(out), "--device", device, "--decoder", str(decoder_folder())],
                          env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 1, proc.stderr[-3000:]
    (record,) = [r for path in (out / "_ledger").glob("*.jsonl") for r in ledger.read(path)]
    assert record["status"] == "aborted" and record["asset_id"] is None
    assert record["reason"].startswith(f"--device {device}: Cycles finds no {device} device on this machine")
    assert record["reason"].endswith("not rendering on the CPU instead")
    assert sorted(p.name for p in out.iterdir()) == ["_ledger"]  # no asset was started
