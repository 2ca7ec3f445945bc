"""Blender side of bench/agreement.py: render every case with Cycles (OSL).

Run in a child process with the pip bpy module (or ``blender -b -P``):
    python bench/agreement_cycles.py JOB.json
JOB.json holds {"cases": [...], "probe", "resolution", "samples", "seed", "out"};
writes OUT/<case>.exr and OUT/cycles_times.json (render seconds per case).
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO), str(REPO / "bench")]

import bpy  # noqa: E402

from agreement_cases import Case  # noqa: E402
from richmat_addon.blender import cycles_builder, preview_scene  # noqa: E402
from richmat_addon.core.preview import PreviewScene  # noqa: E402


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
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    main(Path(argv[0]))
