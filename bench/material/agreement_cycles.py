"""Blender side of bench/material/agreement.py and mtlx_osl_agreement.py beside it: render every case with Cycles (OSL).

Run in a child process with the pip bpy module:
    python -m bench.material.agreement_cycles JOB.json
JOB.json holds {"cases": [...], "probe", "resolution", "samples", "seed", "out"} and,
optionally, "osl" ({case name: OSL file}: that case's surface is the file's shader,
compiled in a Script node, instead of the add-on's) and "threads" (0: all cores);
writes OUT/<case>.exr, OUT/cycles_times.json (render wall seconds per case) and
OUT/cycles_cpu_times.json (the process's CPU seconds over each render, which a
shared machine disturbs less).
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import bpy

from support.agreement_cases import Case
from support.osl_script import script_material
from richmat_addon.blender import cycles_builder
from support import blender_preview_scene
from torch_models.render.preview_scene import PreviewScene


def main(job_path: Path) -> None:
    job = json.loads(job_path.read_text())
    out = Path(job["out"])
    times: dict[str, float] = {}
    cpu: dict[str, float] = {}
    for spec in job["cases"]:
        case = Case(**spec)
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        cycles_builder.enable_osl(scene)
        if case.name in job.get("osl", {}):
            material = script_material(case.name, Path(job["osl"][case.name]).read_text())
        else:
            material = cycles_builder.build_material(case.material(), {}, case.name, node=case.graph_node())
        blender_preview_scene.setup(scene, PreviewScene(resolution=job["resolution"]), Path(job["probe"]),
                                    material, job["samples"], job["seed"])
        if job.get("threads"):
            scene.render.threads_mode, scene.render.threads = "FIXED", job["threads"]
        start, start_cpu = time.perf_counter(), time.process_time()
        blender_preview_scene.render_exr(scene, out / f"{case.name}.exr")
        times[case.name] = time.perf_counter() - start
        cpu[case.name] = time.process_time() - start_cpu
        print(f"cycles {case.name}: {times[case.name]:.1f} s", flush=True)
    (out / "cycles_times.json").write_text(json.dumps(times, indent=1))
    (out / "cycles_cpu_times.json").write_text(json.dumps(cpu, indent=1))


if __name__ == "__main__":
    main(Path(sys.argv[1]))
