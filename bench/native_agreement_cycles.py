"""Blender side of bench/native_agreement.py: every case in Cycles, as OSL and as the native node graph.

Run by bench/native_agreement.py in a child process with the pip bpy module:
    python -m bench.native_agreement_cycles JOB.json
JOB.json holds {"cases": [...], "probe", "resolution", "samples", "seed", "out"}; writes
OUT/<case>_<graph>_0002.exr and OUT/times.json ({case: {graph: {"first": [wall, cpu],
"frame": [wall, cpu]}}}, seconds).

One preview scene, one render thread. Each case's material carries both graphs,
as an uplifted one does; Cycles reads one of them and shades with OSL or SVM to
match. Each graph renders two frames with persistent data, as the farm renders an
orbit: the first one pays for the scene sync and the shader compilation, the
second is the per-frame cost. CPU seconds are the process's: on a shared machine
they move less than wall seconds.
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import bpy

from bench.agreement_cases import Case
from richmat_addon.blender import cycles_builder, preview_scene
from richmat_addon.blender.osl_env import prefer_blender_bundled_modules
from richmat_addon.core.preview import PreviewScene


def main(job_path: Path) -> None:
    prefer_blender_bundled_modules()
    job = json.loads(job_path.read_text())
    out = Path(job["out"])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    cycles_builder.enable_osl(scene)
    preview_scene.setup(scene, PreviewScene(resolution=job["resolution"]), Path(job["probe"]), None,
                        job["samples"], job["seed"])
    scene.render.threads_mode, scene.render.threads = "FIXED", 1
    scene.render.use_persistent_data = True
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.frame_start, scene.frame_end = 1, 2
    ball = bpy.data.node_groups[preview_scene.BALL].nodes["Set Material"].inputs["Material"]
    stamps: list[tuple[float, float]] = []

    def stamp(*_: object) -> None:
        stamps.append((time.perf_counter(), time.process_time()))

    bpy.app.handlers.render_pre.append(stamp)
    bpy.app.handlers.render_post.append(stamp)
    times: dict[str, dict[str, dict[str, list[float]]]] = {}
    for spec in job["cases"]:
        case = Case(**spec)
        material = cycles_builder.build_material(case.material(), {}, case.name, node=case.graph_node())
        ball.default_value = material
        for which in cycles_builder.GRAPHS:
            scene.cycles.shading_system = which == "osl"
            cycles_builder.use_in_cycles(material, which)
            scene.render.filepath = str(out / f"{case.name}_{which}_")
            stamps.clear()
            bpy.ops.render.render(animation=True)
            first, frame = ([end - start for start, end in zip(stamps[i], stamps[i + 1])] for i in (0, 2))
            times.setdefault(case.name, {})[which] = {"first": first, "frame": frame}
        print(f"{case.name}: " + ", ".join(f"{g} {t['frame'][1]:.2f} s" for g, t in times[case.name].items()),
              flush=True)
    (out / "times.json").write_text(json.dumps(times, indent=1))


if __name__ == "__main__":
    main(Path(sys.argv[1]))
