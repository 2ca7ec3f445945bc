"""The add-on as a user installs it: the zip ``make extension`` builds, and the prelude of a Blender
script that installs it into a fresh user folder and drives its operators."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from .paths import REPO


def build_extension() -> Path:
    """``make extension`` (the venv is not re-installed: its stamp is taken as up to date); the zip."""
    subprocess.run(["make", "-o", ".venv/.installed", f"PY={sys.executable}", "extension"], cwd=REPO,
                   check=True, capture_output=True)
    zips = sorted((REPO / "dist").glob("richmat-*.zip"))
    assert zips, "make extension wrote no zip"
    return zips[-1]


def script(body: str, zip_path: Path) -> str:
    return PRELUDE.format(zip=str(zip_path)) + "\n" + body


PRELUDE = r'''
import importlib, json, os, sys, time
from pathlib import Path
import numpy as np
import bpy, addon_utils

ZIP = {zip!r}
MODULE = "bl_ext.user_default.richmat"
# Install exactly as a user would: the built zip, into the temporary user folder.
assert bpy.ops.extensions.package_install_files(filepath=ZIP, repo="user_default",
                                                 enable_on_install=True) == {{"FINISHED"}}
addon_utils.enable(MODULE, default_set=True)
assert MODULE in bpy.context.preferences.addons
bpy.ops.wm.read_homefile(use_empty=True)
scene = bpy.context.scene
reports = []

def run_op(name, **kw):
    """Call bpy.ops.richmat.<name>; returns (result, messages) with reports captured from stdout."""
    op = getattr(bpy.ops.richmat, name)
    try:
        return op(**kw), None
    except RuntimeError as exc:  # ERROR reports raise in background mode
        return {{"CANCELLED"}}, str(exc)

def press(name, **kw):
    """Run an operator as a button does: (sorted result, the lines it reported), its reports read from
    stdout, where Blender prints them in background mode, and its error."""
    log = Path(bpy.app.tempdir or "/tmp") / f"{{name}}_{{os.getpid()}}.log"
    sys.stdout.flush()
    fd, saved = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC), os.dup(1)
    os.dup2(fd, 1)
    try:
        res, err = run_op(name, **kw)
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(fd), os.close(saved)
    return sorted(res), log.read_text() + (err or "")

def write_png(path, rgba):
    h, w, _ = rgba.shape
    img = bpy.data.images.new(Path(path).stem, w, h, alpha=True)
    img.pixels.foreach_set(np.ascontiguousarray(rgba[::-1], np.float32).ravel())
    img.filepath_raw = str(path)
    img.file_format = "PNG"
    img.save()
    bpy.data.images.remove(img)
    return str(path)

def procedural_asset(folder, size=64, name="painted"):
    """A UV sphere with a textured paint material: base colour, packed ORM (roughness G,
    metal B) through Separate Color, and a normal map chain."""
    folder = Path(folder)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16)
    obj = bpy.context.active_object
    bpy.ops.object.shade_smooth()
    obj.name = name
    y, x = np.mgrid[0:size, 0:size] / size
    base = np.stack([0.6 + 0.3 * np.sin(6 * x), 0.2 + 0.1 * y, 0.1 + 0 * x, 1 + 0 * x], -1)
    orm = np.stack([1 + 0 * x, 0.3 + 0.4 * y, 0 * x, 1 + 0 * x], -1)
    nrm = np.stack([0.5 + 0 * x, 0.5 + 0 * x, 1 + 0 * x, 1 + 0 * x], -1)
    mat = bpy.data.materials.new(name + "_mat")
    obj.data.materials.append(mat)
    tree = mat.node_tree
    p = tree.nodes["Principled BSDF"]
    def image_node(file, data):
        node = tree.nodes.new("ShaderNodeTexImage")
        node.image = bpy.data.images.load(write_png(folder / file, data))
        if data is not base:
            node.image.colorspace_settings.name = "Non-Color"
        return node
    b, o, n = image_node("base.png", base), image_node("orm.png", orm), image_node("normal.png", nrm)
    tree.links.new(b.outputs["Color"], p.inputs["Base Color"])
    sep = tree.nodes.new("ShaderNodeSeparateColor")
    tree.links.new(o.outputs["Color"], sep.inputs["Color"])
    tree.links.new(sep.outputs["Green"], p.inputs["Roughness"])
    tree.links.new(sep.outputs["Blue"], p.inputs["Metallic"])
    nm = tree.nodes.new("ShaderNodeNormalMap")
    nm.name = "normal_map"
    tree.links.new(n.outputs["Color"], nm.inputs["Color"])
    tree.links.new(nm.outputs["Normal"], p.inputs["Normal"])
    return obj

def render(size=32, samples=8):
    """A tiny CPU render with one area light; (H, W, 3) linear float."""
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    if scene.camera is None:
        cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
        cam.location = (0, -6, 1)
        cam.rotation_euler = (1.41, 0, 0)
        scene.collection.objects.link(cam)
        scene.camera = cam
        light = bpy.data.objects.new("light", bpy.data.lights.new("light", "AREA"))
        light.data.size = 1.0
        light.rotation_euler = (0.8, 0, 0.6)
        light.data.energy = 800
        light.location = (3, -4, 4)
        scene.collection.objects.link(light)
    return render_exr(Path(bpy.app.tempdir or "/tmp") / f"render_{{os.getpid()}}.exr")

def render_exr(path):
    """The scene rendered by its engine into the EXR ``path``: (H, W, 3) linear, bottom row first."""
    scene = bpy.context.scene
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(path))
    width, height = img.size
    px = np.empty(width * height * 4, np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    return px.reshape(height, width, 4)[..., :3]
'''
