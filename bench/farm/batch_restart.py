"""Issue 5's acceptance run: the farm batch over the sample assets plus broken files, killed and restarted.

Builds an input folder (every model of ../shared/assets/models, the broken and
awkward files of support/batch_inputs.py, a corrupt PLY and a copy of Box
under a unicode name), then
- run A: ``batch/render_dataset.py`` uninterrupted;
- run B: the same command into another folder, SIGKILLed (no clean-up handler
  runs) after ``--kill-after`` seconds, the state on disk recorded, then started
  again and left to finish;
and compares A with B: the same assets done and failed (with the same reasons),
the same files per asset, every PNG/EXR equal by decoded pixels (every subimage),
every JSON equal once its timings (and the manifest's file hashes) are left out,
the MP4 equal byte for byte but for its creation-date tag, every other file equal
byte for byte; only ``logs/`` (the processes' own output) is not compared.

    python -m bench.farm.batch_restart [--work DIR] [--kill-after 300] [--out docs/reports/batch_restart.json]
        [--resolution 64 --frames 4 --samples 16 --fit-steps 5 --max-texture 16]
"""
from __future__ import annotations

import argparse
import json
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from batch import ledger
from batch.options import DEFAULT_DECODER
from bench.common import REPO, add_out_argument, child_env, write_report
from support.paths import SHARED_ASSETS
from support.batch_inputs import make_inputs


def build_inputs(folder: Path, env: dict[str, str]) -> None:
    """The sample models plus files that must fail (or succeed) in instructive ways."""
    make_inputs(folder, folder.parent / "autoexec_ran", env)
    for model in sorted((SHARED_ASSETS / "models").iterdir()):
        shutil.copy(model, folder / model.name)
    shutil.copy(SHARED_ASSETS / "models" / "Box.glb", folder / "Bôx ünïcode.glb")
    (folder / "corrupt.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n\x00\x01")


def records(out: Path) -> dict[str, dict]:
    """The last record per source file that says how it ended (a restart's "skipped" only confirms it)."""
    return {r["source"]: r for path in sorted((out / "_ledger").glob("*.jsonl")) for r in ledger.read(path)
            if r["status"] != "skipped"}


def skipped(out: Path) -> list[str]:
    return sorted({r["source"] for path in (out / "_ledger").glob("*.jsonl") for r in ledger.read(path)
                   if r["status"] == "skipped"})


def finished(out: Path) -> dict[str, Path]:
    """Published asset folders (a manifest, no .partial suffix) by their source file."""
    found = {}
    for folder in out.iterdir():
        manifest = folder / "manifest.json"
        if folder.is_dir() and not folder.name.endswith(".partial") and manifest.is_file():
            found[json.loads(manifest.read_text())["source"]] = folder
    return found


def image_layers(path: Path) -> list[np.ndarray]:
    """Decoded pixels of every subimage (PNG: one)."""
    if path.suffix == ".png":
        return [np.asarray(Image.open(path))]
    import OpenImageIO as oiio

    image = oiio.ImageInput.open(str(path))
    layers, index = [], 0
    while image.seek_subimage(index, 0):
        layers.append(image.read_image(format=oiio.FLOAT))
        index += 1
    image.close()
    return layers


MP4_DATE = re.compile(rb"\d{4}/\d\d/\d\d \d\d:\d\d:\d\d")  # the ffmpeg muxer's creation-date tag


def without_timings(value: Any) -> Any:
    """A JSON value with every ``timings_s`` and ``cpu_s`` entry (and a manifest's file hashes) left out."""
    if isinstance(value, dict):
        return {k: without_timings(v) for k, v in value.items() if k not in ("timings_s", "cpu_s", "files")}
    if isinstance(value, list):
        return [without_timings(v) for v in value]
    return value


def same_file(a: Path, b: Path) -> bool:
    """Equal as data: images by decoded pixels, JSON without timings, MP4 without its date tag."""
    if a.suffix in (".png", ".exr"):
        la, lb = image_layers(a), image_layers(b)
        return len(la) == len(lb) and all(x.shape == y.shape and np.array_equal(x, y, equal_nan=True)
                                          for x, y in zip(la, lb))
    if a.suffix == ".json":
        return without_timings(json.loads(a.read_text())) == without_timings(json.loads(b.read_text()))
    if a.suffix == ".mp4":
        return MP4_DATE.sub(b"", a.read_bytes()) == MP4_DATE.sub(b"", b.read_bytes())
    return a.read_bytes() == b.read_bytes()


def compare(a: Path, b: Path) -> dict:
    """Asset by asset, file by file: what differs between the two outputs."""
    fa, fb = finished(a), finished(b)
    report = {"assets_only_in_a": sorted(set(fa) - set(fb)), "assets_only_in_b": sorted(set(fb) - set(fa)),
              "files_compared": 0, "files_differing": [], "files_missing": []}
    for source in sorted(set(fa) & set(fb)):
        names_a = {p.relative_to(fa[source]) for p in fa[source].rglob("*") if p.is_file()}
        names_b = {p.relative_to(fb[source]) for p in fb[source].rglob("*") if p.is_file()}
        report["files_missing"] += [f"{source}: {n}" for n in sorted(names_a ^ names_b)]
        for name in sorted(names_a & names_b):
            if name.parts[0] == "logs":  # the processes' own output, with their timings
                continue
            report["files_compared"] += 1
            if not same_file(fa[source] / name, fb[source] / name):
                report["files_differing"].append(f"{source}: {name}")
    ra, rb = records(a), records(b)
    report["status_differs"] = sorted(s for s in set(ra) | set(rb)
                                      if (ra.get(s, {}).get("status"), ra.get(s, {}).get("reason"))
                                      != (rb.get(s, {}).get("status"), rb.get(s, {}).get("reason")))
    report["identical"] = not any(report[k] for k in ("assets_only_in_a", "assets_only_in_b", "files_differing",
                                                      "files_missing", "status_differs"))
    return report


def summary(out: Path) -> dict:
    recs = records(out)
    return {"done": sorted(s for s, r in recs.items() if r["status"] == "done"),
            "failed": {s: r["reason"] for s, r in sorted(recs.items()) if r["status"] == "failed"}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--work", type=Path, default=Path("/tmp/richmat_batch_restart"),
                        help="scratch folder (inputs, run_a, run_b); wiped first")
    parser.add_argument("--kill-after", type=float, default=300.0, help="seconds before run B is SIGKILLed")
    add_out_argument(parser, "batch_restart.json")
    parser.add_argument("--resolution", type=int, default=64)
    parser.add_argument("--frames", type=int, default=4)
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--fit-steps", type=int, default=5)
    parser.add_argument("--max-texture", type=int, default=16)
    args = parser.parse_args()

    shutil.rmtree(args.work, ignore_errors=True)
    args.work.mkdir(parents=True)
    env = child_env(args.work / "blender_user")
    inputs = args.work / "inputs"
    build_inputs(inputs, env)

    def command(out: Path) -> list[str]:
        return [sys.executable, str(REPO / "batch" / "render_dataset.py"), "--input", str(inputs),
                "--output", str(out), "--resolution", str(args.resolution), "--frames", str(args.frames),
                "--samples", str(args.samples), "--fit-steps", str(args.fit_steps),
                "--max-texture", str(args.max_texture), "--workers", "1"]

    report: dict = {"settings": vars(args) | {"work": str(args.work), "out": str(args.out)},
                    "inputs": sorted(p.name for p in inputs.iterdir())}
    start = time.perf_counter()
    print("run A (uninterrupted) ...", flush=True)
    subprocess.run(command(args.work / "run_a"), env=env, stdout=subprocess.DEVNULL)
    report["run_a"] = summary(args.work / "run_a") | {"seconds": time.perf_counter() - start}

    print(f"run B: SIGKILL after {args.kill_after:.0f} s ...", flush=True)
    start = time.perf_counter()
    proc = subprocess.Popen(command(args.work / "run_b"), env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        proc.wait(timeout=args.kill_after)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    time.sleep(2)  # the children die of PR_SET_PDEATHSIG
    out_b = args.work / "run_b"
    report["run_b_at_kill"] = {"finished": sorted(finished(out_b)),
                               "partial_folders": sorted(p.name for p in out_b.glob("*.partial"))}
    print(f"  killed with {len(finished(out_b))} assets finished; restarting ...", flush=True)
    restart = subprocess.run(command(out_b), env=env, capture_output=True, text=True)
    report["run_b"] = summary(out_b) | {"seconds": time.perf_counter() - start, "skipped_on_restart": skipped(out_b),
                                         "restart_stderr_tail": restart.stderr[-1500:]}
    report["comparison"] = compare(args.work / "run_a", out_b)
    report["no_partial_left"] = not list(out_b.glob("*.partial")) and not list(
        (args.work / "run_a").glob("*.partial"))
    write_report(args.out, report, [DEFAULT_DECODER])
    c = report["comparison"]
    print(f"A: {len(report['run_a']['done'])} done, {len(report['run_a']['failed'])} failed; "
          f"B: {len(report['run_b']['done'])} done, {len(report['run_b']['failed'])} failed; "
          f"{c['files_compared']} files compared, {len(c['files_differing'])} differ; identical: {c['identical']}")


if __name__ == "__main__":
    main()
