"""The farm as a stock Blender 5.0 runs it: only the modules Blender bundles on the Blender side.

Every process of the run but the fit (the entry script, the orchestrator, each
``blender_job.py`` stage) starts under ``tests/stock_blender/sitecustomize.py``,
an import guard that refuses every module a stock Blender's Python lacks
(torch, tqdm, scipy, trimesh, xatlas, PIL, ...) and logs each refusal. The pip
``bpy`` module stands in for the Blender binary, which these machines lack; the
fit runs in a separate ``--python`` with torch, as on a farm.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

from batch import ledger
from tests.test_batch_render import decoder_folder

REPO = Path(__file__).resolve().parents[1]
GUARD = REPO / "tests" / "stock_blender"


def guarded_run(tmp_path: Path, inputs: Path, out: Path, *extra: str) -> tuple[subprocess.CompletedProcess, list]:
    """``render_dataset.py`` under the guard; the process result and the refused (script, module) pairs."""
    refused = tmp_path / "refused.txt"
    torch_python = tmp_path / "torch-python"  # the fit's interpreter: no guard, as a separate Python on a farm
    torch_python.write_text(f"#!/bin/sh\nexec env -u RICHMAT_STOCK_BLENDER {sys.executable} \"$@\"\n")
    torch_python.chmod(0o755)
    env = dict(os.environ, PYTHONPATH=f"{GUARD}{os.pathsep}{REPO}", RICHMAT_STOCK_BLENDER=str(refused),
               BLENDER_USER_RESOURCES=str(tmp_path / "blender_user"))
    cmd = [sys.executable, str(REPO / "batch" / "render_dataset.py"), "--input", str(inputs), "--output", str(out),
           "--frames", "2", "--resolution", "32", "--samples", "2", "--aov-samples", "1", "--fit-steps", "2",
           "--max-texture", "16", "--decoder", str(decoder_folder()), "--python", str(torch_python),
           "--timeout", "600", "--retries", "0", *extra]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=900)
    pairs = [tuple(line.split()) for line in refused.read_text().splitlines()] if refused.exists() else []
    return proc, pairs


def test_the_farm_runs_with_only_what_a_stock_blender_bundles(shared_assets: Path, tmp_path: Path) -> None:
    inputs, out = tmp_path / "in", tmp_path / "out"
    inputs.mkdir()
    shutil.copy(shared_assets / "models" / "Box.glb", inputs / "Box.glb")  # one material, no UVs
    proc, refused = guarded_run(tmp_path, inputs, out)
    assert proc.returncode == 0, proc.stderr[-4000:]
    # what the Blender side tried and did without: tqdm (a plain progress line instead) and xatlas (Smart UV
    # Project instead, noted)
    assert sorted(set(refused)) == [("blender_job.py", "xatlas"), ("render_dataset.py", "tqdm")], refused
    assert "shard 0000-of-0001 [1/1] done Box-" in proc.stderr
    (record,) = [r for path in (out / "_ledger").glob("*.jsonl") for r in ledger.read(path)]
    assert record["status"] == "done" and record["source"] == "Box.glb"
    manifest = json.loads((out / record["asset_id"] / "manifest.json").read_text())
    assert any("no UVs, unwrapped with Smart UV Project: xatlas is not installed" in n for n in manifest["notes"])
    for name in ("rgb/0000.png", "rgb/0001.png", "passes/0000.exr", "orbit.mp4", "cameras.json", "caption.txt"):
        assert name in manifest["files"], name
    assert manifest["fit"]["torch_version"]  # the fit ran in the --python interpreter, with torch


def test_the_device_check_runs_in_a_stock_blender(tmp_path: Path) -> None:
    inputs = tmp_path / "in"
    inputs.mkdir()
    (inputs / "never_started.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    proc, refused = guarded_run(tmp_path, inputs, tmp_path / "out", "--device", "METAL")  # never on Linux
    assert proc.returncode == 1, proc.stderr[-4000:]
    assert "aborted: --device METAL: this Blender has no METAL backend" in proc.stderr
    assert refused == []  # the orchestrator stopped before it needed a progress bar
