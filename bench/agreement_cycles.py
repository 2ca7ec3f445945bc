"""Blender side of bench/agreement.py: render every case with Cycles (OSL).

Run by bench/agreement.py in a child process with the pip bpy module:
    python -m bench.agreement_cycles JOB.json
JOB.json holds {"cases": [...], "probe", "resolution", "samples", "seed", "out"};
writes OUT/<case>.exr and OUT/cycles_times.json (render seconds per case).
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import bpy

from support.agreement_cases import Case
from richmat_addon.blender import cycles_builder, preview_scene
from richmat_addon.core.preview import PreviewScene


def main(job_path: Path) -> None:
    job = json.loads(job_path.read_text())
    out = Path(job["out"])
    times: dict[str, float] = {}
    for spec in job["cases"]:
        case = Case(**spec)
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        cycles_builder.enable_osl(scene)
        material = cycles_builder.build_material(case.material(), {}, case.name, node=case.graph_node())
        preview_scene.setup(scene, PreviewScene(resolution=job["resolution"]), Path(job["probe"]),
                            material, job["samples"], job["seed"])
        start = time.perf_counter()
        preview_scene.render_exr(scene, out / f"{case.name}.exr")
        times[case.name] = time.perf_counter() - start
        print(f"cycles {case.name}: {times[case.name]:.1f} s", flush=True)
    (out / "cycles_times.json").write_text(json.dumps(times, indent=1))


if __name__ == "__main__":
    main(Path(sys.argv[1]))
