"""The neural preview as Cycles closures against the emission preview it replaced, in two scenes.

For the agreement cases (support/agreement_cases.py, seed 0: per type a dielectric and,
where the type allows, a metal; the shipped encoder's latent of each), renders the
preview ball

* with the torch renderer of the full hybrid decoder (the reference, two seeds: the
  noise floor) and of its closure form (``closure_form.ClosureForm``: what holding
  the gates constant over wo costs, before any renderer);
* in Cycles with the shipped preview shader (``core/neural_osl_hybrid.py``: lobes as
  closures) and with the emission shader of ``--emission-commit`` (the preview before,
  rebuilt from git: its lobe integrated from the world probe), each at two seeds, so
  each has its own noise beside its render seconds;

in two scenes: the probe alone, and the probe plus a sun lamp (an artist's key light).
Writes the JSON, a contact sheet per scene (Cycles closures | Cycles emission | torch
| FLIP of closures, FLIP of emission) and a chart (FLIP per case and render seconds).

    python -m bench.addon.closure_preview [--resolution 32] [--spp 128] [--cycles-spp 64]
        [--emission-commit c516076] [--out docs/reports/closure_preview.json]
"""
from __future__ import annotations

import argparse
import dataclasses
import importlib
import importlib.util
import json
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
import torch

from support.agreement_cases import cases
from bench.common import (FLIP_CONVENTION, REPO, add_out_argument, pyplot, run_python, save_chart,
                          write_report)
from richmat_addon.core.neural_osl import neural_osl_source
from richmat_addon.core.tensor_file import read_safetensors
from torch_models.neural import trained
from torch_models.neural.bsdf import NeuralBsdf
from torch_models.neural.evaluate import DEFAULT_PROBE, KEY_LIGHT, SCENES, BallSetup, ball_image
from torch_models.neural.hybrid.closure_form import closure_model
from torch_models.render.ball import Sun
from torch_models.render.flip import flip_map, mean_flip
from torch_models.render.tonemap import agx

PREVIEW_SHADER_FILES = ("neural_osl.py", "schema.py", "tensor_file.py")

CYCLES = """
import json, sys, time, numpy as np
from pathlib import Path
from support import blender_preview_scene
from support.neural_ball import neural_ball, read_exr, set_material
job = json.loads(Path(sys.argv[1]).read_text())
scene, node = neural_ball(Path(job["shader"]).read_text(), Path(job["probe"]), job["resolution"], job["spp"])
if "probe" in node.inputs:
    node.inputs["probe"].default_value = job["probe"]
if job["sun"] is not None:
    blender_preview_scene.add_sun(scene, *job["sun"])
seconds = {}
for case in job["cases"]:
    set_material(node, case["z"], case["base"])
    for seed in (0, 1):
        scene.cycles.seed = seed
        path = Path(job["out"]) / f"{case['name']}_{seed}.exr"
        start = time.perf_counter()
        blender_preview_scene.render_exr(scene, path)
        seconds[f"{case['name']}_{seed}"] = time.perf_counter() - start
        np.save(path.with_suffix(".npy"), read_exr(path)[..., :3])
(Path(job["out"]) / "seconds.json").write_text(json.dumps(seconds))
"""


def emission_shader(commit: str, tensors: dict[str, np.ndarray], tmp: Path) -> str:
    """The preview shader as ``commit`` generated it (its ``core/neural_osl.py`` and what that imports,
    read from git into a throwaway package registered under its own name)."""
    package = tmp / "preview_then"
    package.mkdir()
    (package / "__init__.py").write_text("")
    for name in PREVIEW_SHADER_FILES:
        source = subprocess.run(["git", "show", f"{commit}:richmat_addon/core/{name}"], cwd=REPO, check=True,
                                capture_output=True, text=True).stdout
        (package / name).write_text(source)
    spec = importlib.util.spec_from_file_location("preview_then", package / "__init__.py",
                                                  submodule_search_locations=[str(package)])
    sys.modules["preview_then"] = importlib.util.module_from_spec(spec)
    try:
        return importlib.import_module("preview_then.neural_osl").neural_osl_source(tensors)
    finally:
        for name in [m for m in sys.modules if m == "preview_then" or m.startswith("preview_then.")]:
            del sys.modules[name]


def torch_images(model: trained.NeuralModel, case: dict, setup: BallSetup, sun: Sun | None) -> dict[str, np.ndarray]:
    """AgX images of the full decoder (seeds 0 and 1) and of its closure form (seed 0)."""
    closure = closure_model(model)
    out = {}
    for name, m, seed in (("full", model, 0), ("full_seed1", model, 1), ("closure_form", closure, 0)):
        bsdf = NeuralBsdf(m, torch.tensor([case["z"]]), torch.tensor([case["base"]]), 1.0)
        out[name] = ball_image(setup, bsdf, seed, sun)
    return out


def cycles_images(shader: str, job_cases: list[dict], sun: Sun | None, args: argparse.Namespace,
                  tmp: Path) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """AgX images ``{case}_{seed}`` of one shader source, and the render seconds of each."""
    tmp.mkdir(parents=True)
    (tmp / "shader.osl").write_text(shader)
    job = {"shader": str(tmp / "shader.osl"), "probe": str(DEFAULT_PROBE), "resolution": args.resolution,
           "spp": args.cycles_spp, "cases": job_cases, "out": str(tmp),
           "sun": None if sun is None else [list(sun.direction), sun.irradiance]}
    (tmp / "job.json").write_text(json.dumps(job))
    (tmp / "job.py").write_text(textwrap.dedent(CYCLES))
    run_python([str(tmp / "job.py"), str(tmp / "job.json")], tmp)
    seconds = json.loads((tmp / "seconds.json").read_text())
    return {k: agx(np.load(tmp / f"{k}.npy")) for k in seconds}, seconds


def scene_rows(name: str, sun: Sun | None, model: trained.NeuralModel, shaders: dict[str, str],
               job_cases: list[dict], setup: BallSetup, args: argparse.Namespace, tmp: Path) -> tuple[list, list]:
    rendered = {kind: cycles_images(src, job_cases, sun, args, tmp / f"{name}_{kind}") for kind, src in shaders.items()}
    rows, sheet = [], []
    for case in job_cases:
        c = case["name"]
        ref = torch_images(model, case, setup, sun)
        row = {"name": c, "torch_noise_floor": mean_flip(ref["full"], ref["full_seed1"]),
               "closure_form_vs_full": mean_flip(ref["full"], ref["closure_form"])}
        maps = []
        for kind, (images, seconds) in rendered.items():
            error, flip = flip_map(ref["full"], images[f"{c}_0"])
            maps.append(error)
            row[kind] = {"flip": flip, "cycles_noise": mean_flip(images[f"{c}_0"], images[f"{c}_1"]),
                         "seconds": float(np.median([seconds[f"{c}_0"], seconds[f"{c}_1"]]))}
        rows.append(row)
        sheet.append((f"{name}: {c}", rendered["closures"][0][f"{c}_0"], rendered["emission"][0][f"{c}_0"],
                      ref["full"], *maps))
        print(f"{name} {c}: " + ", ".join(f"{k} FLIP {row[k]['flip']:.4f} ({row[k]['seconds']:.1f} s)"
                                          for k in shaders) + f", floor {row['torch_noise_floor']:.4f}", flush=True)
    return rows, sheet


def summary(rows: list[dict]) -> dict:
    out = {"torch_noise_floor_median": float(np.median([r["torch_noise_floor"] for r in rows])),
           "closure_form_vs_full_median": float(np.median([r["closure_form_vs_full"] for r in rows])),
           "closure_form_vs_full_worst": float(max(r["closure_form_vs_full"] for r in rows))}
    for kind in ("closures", "emission"):
        out[kind] = {"mean_flip": float(np.mean([r[kind]["flip"] for r in rows])),
                     "worst_flip": float(max(r[kind]["flip"] for r in rows)),
                     "median_cycles_noise": float(np.median([r[kind]["cycles_noise"] for r in rows])),
                     "median_seconds": float(np.median([r[kind]["seconds"] for r in rows]))}
    return out


COLUMNS = ("Cycles closures", "Cycles emission", "torch reference", "FLIP closures", "FLIP emission")


def sheet_image(rows: list, path: Path, scale: int = 4) -> None:
    """One row per case: the COLUMNS, each ball enlarged ``scale`` times, labelled."""
    from PIL import Image, ImageDraw

    def u8(x: np.ndarray) -> np.ndarray:
        return (np.clip(x, 0, 1) * 255 + 0.5).astype(np.uint8).repeat(scale, 0).repeat(scale, 1)

    tiles = [[u8(a), u8(b), u8(c), u8(np.repeat(e1[..., None], 3, -1)), u8(np.repeat(e2[..., None], 3, -1))]
             for _, a, b, c, e1, e2 in rows]
    size, label, header = tiles[0][0].shape[0], 170, 24
    sheet = Image.new("RGB", (label + size * len(COLUMNS), header + size * len(rows)), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for j, name in enumerate(COLUMNS):
        draw.text((label + j * size + 4, 6), name, fill=(0, 0, 0))
    for i, (row, images) in enumerate(zip(rows, tiles)):
        draw.text((4, header + i * size + size // 2 - 6), row[0], fill=(0, 0, 0))
        for j, image in enumerate(images):
            sheet.paste(Image.fromarray(image), (label + j * size, header + i * size))
    sheet.save(path)


def chart(report: dict, path: Path) -> None:
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.5))
    for ax, (scene, block) in zip(axes[:2], report["scenes"].items()):
        names = [r["name"] for r in block["cases"]]
        x = np.arange(len(names))
        for k, (kind, colour) in enumerate((("closures", "tab:blue"), ("emission", "tab:orange"))):
            ax.bar(x + (k - 0.5) * 0.38, [r[kind]["flip"] for r in block["cases"]], 0.38, color=colour,
                   label=f"Cycles {kind} vs torch decoder")
        ax.plot(x, [r["torch_noise_floor"] for r in block["cases"]], "k_", ms=14, label="torch noise floor")
        ax.set_xticks(x, [n.replace("_", "\n", 1) for n in names], fontsize=7)
        ax.set_title(f"scene: {scene}")
        ax.set_ylabel("mean FLIP")
        ax.legend(fontsize=7)
    ax = axes[2]
    for scene, marker in zip(report["scenes"], "os"):
        for kind, colour in (("closures", "tab:blue"), ("emission", "tab:orange")):
            s = report["scenes"][scene]["summary"][kind]
            ax.scatter(s["median_seconds"], s["mean_flip"], c=colour, marker=marker, s=60, label=f"{kind}, {scene}")
    ax.set_xlabel("Cycles seconds per frame (median)")
    ax.set_ylabel("mean FLIP vs the torch decoder")
    ax.set_title("speed against accuracy")
    ax.legend(fontsize=7)
    save_chart(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=int, default=32)
    parser.add_argument("--spp", type=int, default=128, help="torch renderer samples per pixel")
    parser.add_argument("--cycles-spp", type=int, default=64)
    parser.add_argument("--emission-commit", default="c516076", help="the commit whose preview shader was an emission")
    add_out_argument(parser, "closure_preview.json")
    args = parser.parse_args()
    start = time.perf_counter()
    folder = trained.SHIPPED
    model = trained.load(folder)
    setup = BallSetup.default(args.resolution, args.spp, 0)
    tensors = read_safetensors(folder / "weights.safetensors")
    job_cases = []
    for case in cases(0, 2, 0):
        with torch.no_grad():
            z = model.encoder(torch.from_numpy(case.vector())[None])
        job_cases.append({"name": case.name, "z": z[0].tolist(), "base": list(case.base_color)})
    report: dict = {"resolution": args.resolution, "torch_spp": args.spp, "cycles_spp": args.cycles_spp,
                    "emission_commit": args.emission_commit, "sun": dataclasses.asdict(KEY_LIGHT),
                    "flip_convention": FLIP_CONVENTION, "scenes": {}}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        shaders = {"closures": neural_osl_source(tensors),
                   "emission": emission_shader(args.emission_commit, tensors, Path(tmp))}
        for name, sun in SCENES.items():
            rows, sheet = scene_rows(name, sun, model, shaders, job_cases, setup, args, Path(tmp))
            report["scenes"][name] = {"summary": summary(rows), "cases": rows}
            sheet_image(sheet, args.out.with_name(f"{args.out.stem}_{name}.png"))
    report["wall_seconds"] = time.perf_counter() - start
    write_report(args.out, report, [folder])
    chart(report, args.out.with_suffix(".png"))
    for name, block in report["scenes"].items():
        s = block["summary"]
        print(f"{name}: closures {s['closures']['mean_flip']:.4f} / worst {s['closures']['worst_flip']:.4f}, "
              f"emission {s['emission']['mean_flip']:.4f} / worst {s['emission']['worst_flip']:.4f}, "
              f"floor {s['torch_noise_floor_median']:.4f}")


if __name__ == "__main__":
    main()
