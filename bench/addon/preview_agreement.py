"""The add-on's neural preview (OSL in Cycles) against the torch renderer, per type.

For one material per type (support/agreement_cases.py, latent from each decoder's
encoder), renders the preview ball with the torch renderer (``NeuralBsdf``, probe
MIS) and with Cycles running the shader of ``richmat_addon/core/neural_osl.py``,
same probe, scene and networks; reports mean LDR-FLIP (AgX, sRGB, 67 ppd) per
type and the torch-vs-torch noise floor (two seeds). Several weights folders
(``--weights`` again; each names its decoder kind) are measured side by side on
the same materials, each with its FLIP and its Cycles render time. Writes the
JSON and, beside it, a PNG sheet (Cycles | torch | FLIP map, one row per type and
weights folder).

    python -m bench.addon.preview_agreement [--weights RUN ...] [--resolution 48] [--spp 1024]
        [--cycles-spp 384] [--directions 8] [--out docs/reports/preview_agreement.json]

Target (issue 4): mean FLIP <= 0.05.
"""
from __future__ import annotations

import argparse
import json
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
import torch

from support.agreement_cases import cases
from bench.common import (FLIP_CONVENTION, add_out_argument, add_weights_argument, contact_sheet, run_python,
                          weights_folders, write_report)
from richmat_addon.core.schema import CHANNEL_SLICES
from torch_models.neural import trained
from torch_models.neural.model import NeuralModel
from torch_models.neural.bsdf import NeuralBsdf
from torch_models.neural.evaluate import DEFAULT_PROBE, BallSetup
from torch_models.render.ball import render_ball
from torch_models.render.flip import flip_map, mean_flip
from torch_models.render.tonemap import agx

TARGET = 0.05

CYCLES = """
import json, sys, time, numpy as np
from pathlib import Path
from support import blender_preview_scene
from richmat_addon.core.neural_osl import neural_osl_source
from richmat_addon.core.tensor_file import read_safetensors
from support.neural_ball import neural_ball, read_exr, set_material
job = json.loads(Path(sys.argv[1]).read_text())
source = neural_osl_source(read_safetensors(job["weights"]))
scene, node = neural_ball(source, Path(job["probe"]), job["resolution"], job["spp"])
if "probe" in node.inputs:  # the MLP's shader integrates its lobe from the probe; the hybrid's are closures
    node.inputs["probe"].default_value = job["probe"]
    node.inputs["samples"].default_value = job["directions"]
seconds = {}
for case in job["cases"]:
    set_material(node, case["z"], case["base"])
    path = Path(job["out"]) / (case["name"] + ".exr")
    start = time.perf_counter()
    blender_preview_scene.render_exr(scene, path)
    seconds[case["name"]] = time.perf_counter() - start
    np.save(path.with_suffix(".npy"), read_exr(path)[..., :3])
(Path(job["out"]) / "seconds.json").write_text(json.dumps(seconds))
"""


def torch_side(model: NeuralModel, setup: BallSetup, spp: int) -> tuple[list[dict], dict, dict]:
    """The cases' latents and base colours, their torch images and the torch-vs-torch noise floors."""
    job_cases, images, floors = [], {}, {}
    for case in cases(0, 1, 0):
        vector = np.concatenate([np.atleast_1d(case.params[k]) for k in CHANNEL_SLICES]).astype(np.float32)
        with torch.no_grad():
            z = model.encoder(torch.from_numpy(vector)[None])
        base = np.asarray(case.base_color, np.float32)
        bsdf = NeuralBsdf(model, z, torch.as_tensor(base)[None], 1.0)
        with torch.no_grad():
            pair = [render_ball(lambda n: bsdf, setup.env, setup.scene, spp, seed).rgb for seed in (0, 1)]
        images[case.name] = pair[0]
        floors[case.name] = mean_flip(agx(pair[0]), agx(pair[1]))
        job_cases.append({"name": case.name, "z": z[0].tolist(), "base": base.tolist()})
    return job_cases, images, floors


def cycles_side(folder: Path, job_cases: list[dict], args: argparse.Namespace, tmp: Path) -> dict[str, float]:
    """Renders every case with the shader generated from ``folder``'s weights into ``tmp``; the render seconds per case."""
    job = {"weights": str(folder / "weights.safetensors"), "probe": str(DEFAULT_PROBE),
           "resolution": args.resolution, "spp": args.cycles_spp, "directions": args.directions,
           "cases": job_cases, "out": str(tmp)}
    (tmp / "job.json").write_text(json.dumps(job))
    (tmp / "preview_cycles_job.py").write_text(textwrap.dedent(CYCLES))
    run_python([str(tmp / "preview_cycles_job.py"), str(tmp / "job.json")], tmp)
    return json.loads((tmp / "seconds.json").read_text())


def measure(folder: Path, setup: BallSetup, args: argparse.Namespace, sheet: list) -> dict:
    """One weights folder's entry of the report; appends its rows to the contact sheet."""
    model = trained.load(folder)
    kind = model.decoder.kind
    job_cases, torch_images, floors = torch_side(model, setup, args.spp)
    print(f"{kind} {folder}: torch done", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        seconds = cycles_side(folder, job_cases, args, Path(tmp))
        rows = []
        for case in job_cases:
            name = case["name"]
            cycles, reference = agx(np.load(Path(tmp) / (name + ".npy"))), agx(torch_images[name])
            error, flip = flip_map(reference, cycles)
            sheet.append((f"{kind}: {name}", cycles, reference, error))
            rows.append({"name": name, "flip": flip, "torch_noise_floor": floors[name],
                         "cycles_render_seconds": seconds[name]})
            print(f"{kind} {name}: FLIP {flip:.4f} (torch vs torch {floors[name]:.4f}), "
                  f"Cycles {seconds[name]:.1f} s", flush=True)
    mean = float(np.mean([r["flip"] for r in rows]))
    return {"weights": str(folder), "kind": kind, "decoder_sha256": model.digest, "mean_flip": mean,
            "worst_flip": max(r["flip"] for r in rows), "passed": mean <= TARGET,
            "cycles_render_seconds": sum(seconds.values()), "cases": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_weights_argument(parser)
    parser.add_argument("--resolution", type=int, default=48)
    parser.add_argument("--spp", type=int, default=1024, help="torch renderer samples per pixel")
    parser.add_argument("--cycles-spp", type=int, default=384)
    parser.add_argument("--directions", type=int, default=8, help="the MLP shader's directions per shading point")
    add_out_argument(parser, "preview_agreement.json")
    args = parser.parse_args()
    folders = weights_folders(args)

    start = time.perf_counter()
    setup = BallSetup.default(args.resolution, args.spp, 0)
    sheet: list = []
    runs = [measure(folder, setup, args, sheet) for folder in folders]
    report = {"resolution": args.resolution, "torch_spp": args.spp, "cycles_spp": args.cycles_spp,
              "directions": args.directions, "flip_convention": FLIP_CONVENTION,
              "target": TARGET, "passed": all(r["passed"] for r in runs), "runs": runs,
              "wall_seconds": time.perf_counter() - start}
    write_report(args.out, report, folders)
    contact_sheet(sheet, args.out.with_suffix(".png"))
    for r in runs:
        print(f"{r['kind']} {r['weights']}: mean FLIP {r['mean_flip']:.4f} (target {TARGET}), "
              f"Cycles {r['cycles_render_seconds']:.1f} s")


if __name__ == "__main__":
    main()
