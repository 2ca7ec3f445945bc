"""The fit as the add-on runs it, on the sample assets at their full texture size.

Each asset is enhanced (``--type``, default 2: clearcoat on every material) at the
resolution of its own textures, then every material folder is fitted with the
add-on's default steps against each decoder given, and the seconds of each stage
are recorded: reading and deduplicating the texels, the latent fit, the energy
check (the MLP's furnace and refit; the hybrid is bounded by construction and
only reads its bound) and writing the latent textures.

The MLP's furnace is linear in the unique vectors it checks and takes tens of
minutes on a 1k material; ``--furnace-sample N`` times it on N of them and
scales the seconds to all (marked ``extrapolated``), so a run stays short.

    python -m bench.neural.fit_full_size [--assets WaterBottle ...] [--weights RUN ...] [--steps 300]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from bench.common import add_out_argument, add_weights_argument, pyplot, save_chart, weights_folders, write_report
from support.paths import SHARED_ASSETS
from torch_models.cli import main as cli
from torch_models.neural import trained
from torch_models.neural.model import NeuralModel
from torch_models.neural.energy import fit_bounded
from torch_models.neural.fit.latents import fit_latents
from torch_models.neural.fit.material_vectors import read_vectors

ASSETS = ("WaterBottle", "CesiumMilkTruck", "FlightHelmet")
ADDON_FIT_STEPS = 300  # richmat_addon/blender/props.py fit_steps default
TARGET_SECONDS = 120.0


def enhance_asset(name: str, kind: str, out: Path) -> None:
    """The sample asset ``name`` enhanced with type ``kind`` into ``out``, at its textures' own size."""
    if cli(["enhance", str(SHARED_ASSETS / "models" / f"{name}.glb"), "--out", str(out), "--type", kind,
            "--on-metal", "remap"]) != 0:
        raise SystemExit(f"enhance failed on {name}")


def fit_stages(model: NeuralModel, folder: Path, steps: int, furnace_sample: int) -> dict:
    """Seconds per stage of fitting one material folder."""
    t0 = time.perf_counter()
    mv = read_vectors(folder)
    t1, c1 = time.perf_counter(), time.process_time()
    z = fit_latents(model, mv.unique, steps)
    t2, c2 = time.perf_counter(), time.process_time()
    checked = np.arange(len(z))
    if not model.decoder.bounded and len(z) > furnace_sample:
        checked = np.random.default_rng(0).choice(len(z), furnace_sample, replace=False)
    bounded = fit_bounded(model, mv.unique[checked], z[torch.from_numpy(checked)])
    t3 = time.perf_counter()
    if mv.shape is not None:
        mv.texels(z)  # the scatter to texture space the writer does
    t4 = time.perf_counter()
    energy = (t3 - t2) * len(z) / len(checked)
    return {"texels": int(np.prod(mv.shape)) if mv.shape else 1, "shape": list(mv.shape or ()),
            "unique_vectors": len(mv.unique), "read_seconds": t1 - t0, "fit_seconds": t2 - t1,
            "fit_cpu_seconds": c2 - c1,
            "energy_seconds": energy, "energy_extrapolated": len(checked) < len(z),
            "scatter_seconds": t4 - t3, "total_seconds": (t1 - t0) + (t2 - t1) + energy + (t4 - t3),
            "furnace": bounded.counts()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--assets", nargs="+", default=list(ASSETS))
    parser.add_argument("--type", default="2", help="enhancement type for every material (default: 2)")
    parser.add_argument("--steps", type=int, default=ADDON_FIT_STEPS)
    parser.add_argument("--furnace-sample", type=int, default=512, help="unique vectors the MLP's furnace is timed on")
    add_weights_argument(parser)
    add_out_argument(parser, "fit_full_size.json")
    args = parser.parse_args()
    folders = weights_folders(args)
    models = [trained.load(f) for f in folders]

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.assets:
            out = Path(tmp) / name
            t0 = time.perf_counter()
            enhance_asset(name, args.type, out)
            enhance_seconds = time.perf_counter() - t0
            for material in sorted(p.parent for p in out.glob("*/params.json")):
                for folder, model in zip(folders, models):
                    stages = fit_stages(model, material, args.steps, args.furnace_sample)
                    rows.append({"asset": name, "material": material.name, "kind": model.decoder.kind,
                                 "decoder_sha256": model.digest, "enhance_seconds_asset": enhance_seconds, **stages})
                    print(f"{name}/{material.name} {model.decoder.kind}: {stages['shape']} texels, "
                          f"{stages['unique_vectors']} unique, read {stages['read_seconds']:.1f} s, fit "
                          f"{stages['fit_seconds']:.1f} s, energy {stages['energy_seconds']:.1f} s"
                          f"{' (extrapolated)' if stages['energy_extrapolated'] else ''}, total "
                          f"{stages['total_seconds']:.1f} s", flush=True)
    report = {"steps": args.steps, "type": args.type, "threads": torch.get_num_threads(),
              "target_seconds": TARGET_SECONDS, "materials": rows}
    write_report(args.out, report, folders)
    chart(report, args.out.with_suffix(".png"))


def chart(report: dict, path: Path) -> None:
    plt = pyplot()

    rows = report["materials"]
    labels = [f"{r['asset']}/{r['material']}\n{r['kind']}, {r['shape'][0]}x{r['shape'][1] if len(r['shape']) > 1 else 1}"
              for r in rows]
    stages = (("read_seconds", "read + dedupe"), ("fit_seconds", f"fit ({report['steps']} steps)"),
              ("energy_seconds", "energy check (hatched: extrapolated)"), ("scatter_seconds", "scatter to texels"))
    fig, ax = plt.subplots(figsize=(10, 0.5 * len(rows) + 1.8))
    left = np.zeros(len(rows))
    for (key, label), colour in zip(stages, plt.cm.tab10.colors):
        values = np.array([r[key] for r in rows])
        hatches = ["//" if key == "energy_seconds" and r["energy_extrapolated"] else "" for r in rows]
        bars = ax.barh(range(len(rows)), values, left=left, color=colour, label=label)
        for bar, hatch in zip(bars, hatches):
            bar.set_hatch(hatch)
        left += values
    ax.axvline(report["target_seconds"], color="red", ls="--", label=f"target {report['target_seconds']:.0f} s")
    ax.set_xscale("symlog", linthresh=10)
    ax.set_yticks(range(len(rows)), labels, fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel(f"seconds per material ({report['threads']} threads)")
    ax.set_title("Fit at full texture size, per stage")
    ax.legend(fontsize=7, loc="lower right")
    save_chart(fig, path)


if __name__ == "__main__":
    main()
