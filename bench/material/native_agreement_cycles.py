"""Blender side of bench/material/native_agreement.py and native_gpu.py beside it: every case in every configuration.

Run in a child process with the pip bpy module:
    python -m bench.material.native_agreement_cycles JOB.json
JOB.json holds {"cases": [...], "probe", "resolution", "samples", "seed", "out"} and,
optionally, "configs" (default ``CPU_CONFIGS``: Cycles on the CPU reading the OSL
graph, then the native one; a configuration's own "samples" overrides the job's, and
an EEVEE one with "eevee_form": false reads the native form Cycles reads, rendering
only the cases where EEVEE's own form differs, and a configuration's "settings" maps
scene properties by dotted path, such as "eevee.use_fast_gi" or "world.probe_resolution",
to the values it renders with),
"frames" (default ``FRAMES``) and "control" (also render a plain Principled BSDF
ball, which tells a compiled EEVEE shader from EEVEE's fallback). A job with "asset",
the folder of the farm's prepare stage (``batch/blender_job.py prepare``), and "name"
renders that asset instead of the ball: its materials as the farm builds them (native
graph), seen by the farm's camera at its first frame, under the preview probe. Writes
OUT/<case>_<label>_<frame>.exr, OUT/times.json ({case: {label: {"first": [wall, cpu],
"frame": [wall, cpu]}}}, seconds; a configuration whose device is missing is left out)
and OUT/devices.json ({label: the devices it rendered on; for EEVEE, the OpenGL renderer,
such as Mesa's llvmpipe on a machine without a GPU}), adding to those files
when they are there.

One preview scene, one render thread. Each case's material carries both graphs,
as an uplifted one does; Cycles reads the configuration's graph and shades with
OSL or SVM to match, EEVEE reads the native graph. Each configuration renders ``frames``
frames with persistent data, as the farm renders an orbit: the first one pays for
the scene sync and the shader compilation, the fastest of the others is the
per-frame cost (the least disturbed by other jobs on a shared machine; the first, when
there is one frame). CPU
seconds are the process's: there they move less than wall seconds.

The main processes import this module's constants, so bpy is imported inside.
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from support.agreement_cases import Case
from torch_models.render.preview_scene import PreviewScene

if TYPE_CHECKING:
    import bpy

# label, render engine, device ("CPU" or a Cycles compute device type; EEVEE ignores it), graph Cycles reads.
CPU_CONFIGS = [{"label": g, "engine": "CYCLES", "device": "CPU", "graph": g} for g in ("osl", "native")]
CONTROL = "control"  # the plain Principled BSDF ball's case name
FRAMES = 3


def use(scene: bpy.types.Scene, config: dict, samples: int) -> list[str]:
    """Set the scene up for ``config``; the names of the devices it renders on, none when they are missing."""
    import bpy

    from support import blender_preview_scene

    scene.render.engine = config["engine"]
    if blender_preview_scene.BALL in bpy.data.node_groups:
        blender_preview_scene.use_mesh_ball(config["engine"] != "CYCLES")
    samples = config.get("samples", samples)
    if config["engine"] != "CYCLES":
        scene.eevee.taa_render_samples = samples
        return ["GPU (EEVEE)"]  # named after the render: background mode opens OpenGL only to render
    scene.cycles.samples = samples
    scene.cycles.shading_system = config["graph"] == "osl"
    scene.cycles.device = "CPU" if config["device"] == "CPU" else "GPU"
    if config["device"] == "CPU":
        return ["CPU"]
    prefs = bpy.context.preferences.addons["cycles"].preferences
    try:
        prefs.compute_device_type = config["device"]
    except TypeError:  # not a device type this build knows
        return []
    prefs.get_devices()
    for device in prefs.devices:
        device.use = device.type == config["device"]
    return [device.name for device in prefs.devices if device.use]


def set_property(scene: bpy.types.Scene, path: str, value: object) -> object:
    """Set the property at dotted ``path`` under ``scene`` to ``value``; its value before."""
    *owners, name = path.split(".")
    owner = scene
    for attribute in owners:
        owner = getattr(owner, attribute)
    before = getattr(owner, name)
    setattr(owner, name, value)
    return before


def use_in_eevee(material: bpy.types.Material, own_form: bool) -> bool:
    """Link EEVEE's output to EEVEE's own form of the native graph or to the form Cycles reads; False
    when asked for Cycles' form of a material that has no other (EEVEE would draw the same)."""
    from richmat_addon.blender import cycles_builder, native_builder

    nodes = material.node_tree.nodes
    if native_builder.EEVEE_NODE not in nodes:
        return own_form
    source = nodes[native_builder.EEVEE_NODE if own_form else native_builder.NODE]
    material.node_tree.links.new(source.outputs[0], nodes[cycles_builder.EEVEE_OUTPUT_NODE].inputs["Surface"])
    return True


def use_asset(scene: bpy.types.Scene, work: Path) -> None:
    """Give the prepared asset's slots in ``scene`` (opened from ``work``/scene.blend) their native materials
    and look at it with the farm's camera at its first frame (seed 0, whatever the job's seed)."""
    from batch import bl_render, dataset_material
    from batch.blender_job import enhanced_slots

    prepared = json.loads((work / "asset.json").read_text(encoding="utf-8"))
    for slot, beauty in enhanced_slots(scene, prepared, work, "native", dataset_material.beauty):
        slot.material = beauty
    bl_render.orbit(scene, 1, bl_render.start_azimuth(prepared["asset_id"], 0))


def ball_materials(job: dict) -> list[tuple[str, bpy.types.Material | None]]:
    """The job's cases as materials carrying both graphs, and the plain Principled ball where it asks."""
    import bpy

    from richmat_addon.blender import cycles_builder

    materials: list[tuple[str, bpy.types.Material | None]] = [
        (c.name, cycles_builder.build_material(c.material(), {}, c.name, node=c.graph_node()))
        for c in (Case(**spec) for spec in job["cases"])]
    if job.get("control"):
        materials.append((CONTROL, bpy.data.materials.new(CONTROL)))
    return materials


def read_json(path: Path) -> dict:
    return json.loads(path.read_text()) if path.exists() else {}


def main(job_path: Path) -> None:
    import bpy

    from richmat_addon.blender import cycles_builder
    from support import blender_preview_scene
    from richmat_addon.blender.osl_env import prefer_blender_bundled_modules

    prefer_blender_bundled_modules()
    job = json.loads(job_path.read_text())
    out = Path(job["out"])
    configs = job.get("configs", CPU_CONFIGS)
    asset = Path(job["asset"]) if "asset" in job else None
    if asset is None:
        bpy.ops.wm.read_factory_settings(use_empty=True)
    else:
        bpy.ops.wm.open_mainfile(filepath=str(asset / "scene.blend"), load_ui=False, use_scripts=False)
    scene = bpy.context.scene
    blender_preview_scene.setup(scene, PreviewScene(resolution=job["resolution"]), Path(job["probe"]), None,
                                job["samples"], job["seed"], with_ball=asset is None)
    scene.render.film_transparent = True  # the alpha says which pixels are the ball's or the asset's
    if asset is not None:
        use_asset(scene, asset)  # before the frame range: the farm's camera sets its own
    scene.render.threads_mode, scene.render.threads = "FIXED", 1
    scene.render.use_persistent_data = True
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.frame_start, scene.frame_end = 1, job.get("frames", FRAMES)
    stamps: list[tuple[float, float]] = []

    def stamp(*_: object) -> None:
        stamps.append((time.perf_counter(), time.process_time()))

    bpy.app.handlers.render_pre.append(stamp)
    bpy.app.handlers.render_post.append(stamp)
    # None: the asset's own materials (use_asset), on no ball
    materials = ball_materials(job) if asset is None else [(job["name"], None)]
    ball = None if asset is not None else \
        bpy.data.node_groups[blender_preview_scene.BALL].nodes["Set Material"].inputs["Material"]
    # Runs into the same folder add to its records (a GPU machine can give EEVEE and Cycles separate time limits).
    times: dict[str, dict[str, dict[str, list[float]]]] = read_json(out / "times.json")
    devices: dict[str, list[str]] = read_json(out / "devices.json")
    for name, material in materials:
        if ball is not None:
            ball.default_value = material
        for config in configs:
            devices[config["label"]] = use(scene, config, job["samples"])
            if not devices[config["label"]]:
                continue
            if material is not None and cycles_builder.cycles_graph(material) is not None:
                cycles_builder.use_in_cycles(material, config["graph"])
            if (config["engine"] != "CYCLES" and material is not None
                    and not use_in_eevee(material, config.get("eevee_form", True))):
                continue
            scene.render.filepath = str(out / f"{name}_{config['label']}_")
            saved = {path: set_property(scene, path, value) for path, value in config.get("settings", {}).items()}
            stamps.clear()
            bpy.ops.render.render(animation=True)
            for path, value in saved.items():
                set_property(scene, path, value)
            if config["engine"] != "CYCLES":
                import gpu

                devices[config["label"]] = [gpu.platform.renderer_get()]
            seconds = [[end - start for start, end in zip(stamps[i], stamps[i + 1])] for i in range(0, len(stamps), 2)]
            times.setdefault(name, {})[config["label"]] = {"first": seconds[0],
                                                           "frame": [min(column) for column in zip(*(seconds[1:] or seconds))]}
        print(f"{name}: " + ", ".join(f"{label} {t['frame'][1]:.2f} s" for label, t in times.get(name, {}).items()),
              flush=True)
        # After every case, so that a run stopped by a time limit keeps what it finished.
        (out / "times.json").write_text(json.dumps(times, indent=1))
        (out / "devices.json").write_text(json.dumps({label: names for label, names in devices.items() if names}))


if __name__ == "__main__":
    main(Path(sys.argv[1]))
