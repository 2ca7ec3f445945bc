"""Blender side of a sheen measurement (bench/material/calibrate_sheen.py, tests/test_closure_sheen.py):
Cycles' sheen closure.

Spheres of the sheen lobe alone (one per roughness), plus one white Lambertian
sphere, seen by an orthographic camera (every pixel has the same view direction
-y) and lit only by a sun of zero angle (a delta light, so each pixel is
f(wi, wo) cos(theta_o) times the sun's strength, without noise). One render per
sun direction.

    python -m support.sheen_cycles JOB.json
JOB.json: {"roughness": [...], "suns": [[x, y, z], ...], "px_per_unit": P, "out": DIR}
writes DIR/sun_<k>.exr and DIR/layout.json (sphere centres in pixels, radius in pixels).
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import bpy
from mathutils import Vector

from richmat_addon.blender import cycles_builder
from support import blender_preview_scene
from richmat_addon.core import graph
from richmat_addon.core.maps import EnhancedMaterial, ParamMap
from richmat_addon.core.schema import PARAMS

COLUMNS = 8
SPACING = 2.2  # sphere centres, in units of the radius 1


def _material(roughness: float) -> bpy.types.Material:
    params = {p.name: ParamMap.constant(*(p.default if isinstance(p.default, tuple) else (p.default,)))
              for p in PARAMS}
    params["dust_weight"] = ParamMap.constant(1.0)
    params["dust_roughness"] = ParamMap.constant(roughness)
    mat = EnhancedMaterial(f"sheen_{roughness:.4f}", -1, 0, ParamMap.constant(1.0, 1.0, 1.0), params)
    return cycles_builder.build_material(mat, {}, mat.name, node=graph.DUST)


def _diffuse() -> bpy.types.Material:
    mat = bpy.data.materials.new("white_diffuse")
    tree = mat.node_tree
    tree.nodes.clear()
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")  # roughness 0: Lambertian
    diffuse.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(diffuse.outputs["BSDF"], out.inputs["Surface"])
    return mat


def main(job_path: Path) -> None:
    job = json.loads(job_path.read_text())
    out = Path(job["out"])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    cycles_builder.enable_osl(scene)
    materials = [_material(r) for r in job["roughness"]] + [_diffuse()]
    rows = math.ceil(len(materials) / COLUMNS)
    centres = []
    for k, mat in enumerate(materials):
        obj = blender_preview_scene._ball_object(1.0, mat)
        obj.location = ((k % COLUMNS) * SPACING, 0.0, -(k // COLUMNS) * SPACING)
        obj.visible_shadow = False  # spheres must not shade their neighbours
        scene.collection.objects.link(obj)
        centres.append(obj.location.copy())

    ppu = job["px_per_unit"]
    width, height = round(COLUMNS * SPACING * ppu), round(rows * SPACING * ppu)
    cam_data = bpy.data.cameras.new("ortho")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = COLUMNS * SPACING
    cam = bpy.data.objects.new("ortho", cam_data)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)  # looking along +y
    cam.location = ((COLUMNS - 1) * SPACING / 2, -10.0, -(rows - 1) * SPACING / 2)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.world = None
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.film_transparent = True
    scene.cycles.samples = 4
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.pixel_filter_type = "BOX"
    scene.cycles.filter_width = 0.01  # point-sample pixel centres: no mixing at sphere edges
    scene.cycles.sample_clamp_direct = scene.cycles.sample_clamp_indirect = 0.0
    scene.cycles.max_bounces = 0  # direct light only: no light between spheres

    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 1.0
    sun.data.angle = 0.0
    scene.collection.objects.link(sun)
    for k, direction in enumerate(job["suns"]):
        # A sun shines along its local -z: point that axis away from ``direction``.
        sun.rotation_euler = Vector(direction).to_track_quat("Z", "Y").to_euler()
        blender_preview_scene.render_exr(scene, out / f"sun_{k}.exr")
    cx = [(c.x - cam.location.x) / cam_data.ortho_scale * width + width / 2 for c in centres]
    cy = [height / 2 - (c.z - cam.location.z) / cam_data.ortho_scale * width for c in centres]
    (out / "layout.json").write_text(json.dumps({"centres_px": list(zip(cx, cy)), "radius_px": width /
                                                 cam_data.ortho_scale, "width": width, "height": height}))


if __name__ == "__main__":
    main(Path(sys.argv[1]))
