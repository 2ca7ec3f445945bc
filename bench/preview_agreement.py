"""The add-on's neural preview (OSL in Cycles) against the torch renderer, per type.

For one material per type (bench/agreement_cases.py, latent from the encoder),
renders the preview ball with the torch renderer (``NeuralBsdf``, probe MIS) and
with Cycles running the shader of ``richmat_addon/core/neural_osl.py``, same
probe, scene and networks; reports mean LDR-FLIP (AgX, sRGB, 67 ppd) per type
and the torch-vs-torch noise floor (two seeds). Writes the JSON and, beside it,
a PNG sheet (Cycles | torch | FLIP map, one row per type).

    python bench/preview_agreement.py [--weights RUN] [--resolution 48] [--spp 1024]
        [--cycles-spp 384] [--directions 8] [--out docs/preview_agreement.json]

Target (issue 4): mean FLIP <= 0.05.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
import torch

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO), str(REPO / "bench")]

from agreement import contact_sheet  # noqa: E402
from agreement_cases import cases  # noqa: E402
from richmat_addon.core.schema import CHANNEL_SLICES  # noqa: E402
from torch_models.neural import weights  # noqa: E402
from torch_models.neural.bsdf import NeuralBsdf  # noqa: E402
from torch_models.neural.evaluate import DEFAULT_PROBE, BallSetup  # noqa: E402
from torch_models.render.ball import render_ball  # noqa: E402
from torch_models.render.flip import flip_map, mean_flip  # noqa: E402
from torch_models.render.tonemap import agx  # noqa: E402

TARGET = 0.05

CYCLES = """
import json, sys, numpy as np, bpy
from pathlib import Path
from richmat_addon.blender.osl_env import prefer_blender_bundled_modules
prefer_blender_bundled_modules()
from richmat_addon.blender import cycles_builder, preview_scene
from richmat_addon.core.preview import PreviewScene
from richmat_addon.core.neural_osl import neural_osl_source, read_safetensors
job = json.loads(Path(sys.argv[1]).read_text())
bpy.ops.wm.read_homefile(use_empty=True)
scene = bpy.context.scene
mat = bpy.data.materials.new("neural")
tree = mat.node_tree
tree.nodes.clear()
text = bpy.data.texts.new("neural.osl")
text.from_string(neural_osl_source(read_safetensors(job["weights"])))
node = tree.nodes.new("ShaderNodeScript")
node.mode, node.script = "INTERNAL", text
cycles_builder.compile_script_node(node)
tree.links.new(node.outputs["BSDF"], tree.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
preview_scene.setup(scene, PreviewScene(resolution=job["resolution"]), Path(job["probe"]), mat, job["spp"])
scene.cycles.shading_system = True
node.inputs["probe"].default_value = job["probe"]
node.inputs["samples"].default_value = job["directions"]
res = job["resolution"]
for case in job["cases"]:
    node.inputs["latent_0"].default_value = case["z"][:3]
    node.inputs["latent_1"].default_value = case["z"][3:]
    node.inputs["base_color"].default_value = (*case["base"], 1.0)
    path = Path(job["out"]) / (case["name"] + ".exr")
    preview_scene.render_exr(scene, path)
    img = bpy.data.images.load(str(path))
    px = np.empty(res * res * 4, np.float32)
    img.pixels.foreach_get(px)
    np.save(path.with_suffix(".npy"), px.reshape(res, res, 4)[::-1, :, :3])
    bpy.data.images.remove(img)
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--weights", type=Path, default=weights.SHIPPED)
    parser.add_argument("--resolution", type=int, default=48)
    parser.add_argument("--spp", type=int, default=1024, help="torch renderer samples per pixel")
    parser.add_argument("--cycles-spp", type=int, default=384)
    parser.add_argument("--directions", type=int, default=8, help="shader directions per shading point")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "preview_agreement.json")
    args = parser.parse_args()

    start = time.perf_counter()
    model = weights.load(args.weights)
    setup = BallSetup.default(args.resolution, args.spp, 0)
    drawn = cases(0, 1, 0)
    job_cases, torch_images, floors = [], {}, {}
    for case in drawn:
        vector = np.concatenate([np.atleast_1d(case.params[k]) for k in CHANNEL_SLICES]).astype(np.float32)
        with torch.no_grad():
            z = model.encoder(torch.from_numpy(vector)[None])
        base = np.asarray(case.base_color, np.float32)
        bsdf = NeuralBsdf(model, z, torch.as_tensor(base)[None], 1.0)
        with torch.no_grad():
            images = [render_ball(lambda n: bsdf, setup.env, setup.scene, args.spp, seed).rgb for seed in (0, 1)]
        torch_images[case.name] = images[0]
        floors[case.name] = mean_flip(agx(images[0]), agx(images[1]))
        job_cases.append({"name": case.name, "z": z[0].tolist(), "base": base.tolist()})
        print(f"{case.name}: torch done", flush=True)

    with tempfile.TemporaryDirectory() as tmp:
        job = {"weights": str(args.weights / "weights.safetensors"), "probe": str(DEFAULT_PROBE),
               "resolution": args.resolution, "spp": args.cycles_spp, "directions": args.directions,
               "cases": job_cases, "out": tmp}
        (Path(tmp) / "job.json").write_text(json.dumps(job))
        (Path(tmp) / "preview_cycles_job.py").write_text(textwrap.dedent(CYCLES))
        subprocess.run([sys.executable, str(Path(tmp) / "preview_cycles_job.py"), str(Path(tmp) / "job.json")],
                       check=True, capture_output=True,
                       env={**os.environ, "PYTHONPATH": str(REPO), "BLENDER_USER_RESOURCES": tmp})
        rows, sheet = [], []
        for case in job_cases:
            cycles, reference = agx(np.load(Path(tmp) / (case["name"] + ".npy"))), agx(torch_images[case["name"]])
            error, flip = flip_map(reference, cycles)
            sheet.append((case["name"], cycles, reference, error))
            rows.append({"name": case["name"], "flip": flip, "torch_noise_floor": floors[case["name"]]})
            print(f"{case['name']}: FLIP {flip:.4f} (torch vs torch {floors[case['name']]:.4f})", flush=True)
    mean = float(np.mean([r["flip"] for r in rows]))
    report = {"resolution": args.resolution, "torch_spp": args.spp, "cycles_spp": args.cycles_spp,
              "directions": args.directions, "weights": str(args.weights), "decoder_sha256": model.digest,
              "flip_convention": "LDR-FLIP on AgX-tone-mapped sRGB, 67.02 pixels per degree",
              "mean_flip": mean, "worst_flip": max(r["flip"] for r in rows), "target": TARGET,
              "passed": mean <= TARGET, "cases": rows,
              "wall_seconds": time.perf_counter() - start}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))
    contact_sheet(sheet, args.out.with_suffix(".png"))
    print(f"mean FLIP {mean:.4f} (target {TARGET})")


if __name__ == "__main__":
    main()
