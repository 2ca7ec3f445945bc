"""Blender side, render: the dataset's camera orbit, light, Cycles settings and outputs.

Two passes over the orbit. The beauty pass path traces the enhanced materials,
as OSL or as the native node graph (AgX, PNG through the scene output). The intrinsics pass shades with
SVM, because Cycles writes no AOVs under OSL: a few samples, no bounces, no
denoising, and through the compositor's File Output node one multilayer EXR
per frame with world normals and positions (Cycles passes) and the AOVs
``basecolor``, ``latent_a``, ``latent_b`` and ``coverage``. AOVs are neither
tone-mapped nor denoised; the EXR holds scene values.
"""
from __future__ import annotations

import hashlib
import math
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

import bpy
from mathutils import Vector

AOVS = {"basecolor": "COLOR", "latent_a": "COLOR", "latent_b": "COLOR", "coverage": "VALUE"}
PASSES = ("Normal", "Position")
LENS_MM, SENSOR_MM = 35.0, 32.0
ELEVATION_DEG, ELEVATION_SWING_DEG = 25.0, 10.0
# The unit cube's bounding sphere (radius sqrt(3)/2) fills the frame with this margin.
FRAMING_MARGIN = 1.08


class DeviceMissing(Exception):
    """The asked-for Cycles device is not on this machine (or not in this Blender)."""


def use_device(scene: bpy.types.Scene, device: str) -> None:
    """Render ``scene`` on ``device`` ("CPU" or a Cycles GPU backend) with every such GPU and no CPU;
    raise ``DeviceMissing`` rather than let Cycles fall back to the CPU."""
    scene.render.engine = "CYCLES"
    if device == "CPU":
        scene.cycles.device = "CPU"
        return
    prefs = bpy.context.preferences.addons["cycles"].preferences
    backends = [t[0] for t in prefs.get_device_types(bpy.context) if t[0] != "NONE"]
    if device not in backends:
        raise DeviceMissing(f"--device {device}: this Blender has no {device} backend (it has "
                            f"{', '.join(backends) or 'none'}); not rendering on the CPU instead")
    prefs.compute_device_type = device
    gpus = [d for d in prefs.get_devices_for_type(device) if d.type == device]
    if not gpus:
        listed = ", ".join(f"{d.name} ({d.type})" for d in prefs.devices) or "nothing"
        raise DeviceMissing(f"--device {device}: Cycles finds no {device} device on this machine (it lists "
                            f"{listed}); not rendering on the CPU instead")
    for d in prefs.devices:
        d.use = d.type == device
    scene.cycles.device = "GPU"


def configure_cycles(scene: bpy.types.Scene, resolution: int, samples: int, threshold: float,
                     threads: int, graph: str = "osl", prefilter: str = "fast", quality: str = "high",
                     device: str = "CPU") -> None:
    """The beauty pass; ``graph`` "osl" shades with OSL (the Script node runs only there), "native" with SVM;
    ``prefilter`` is OIDN's for its albedo and normal passes (``options.DENOISE_PREFILTERS``), ``quality`` its
    network (``options.DENOISE_QUALITIES``); ``device`` as
    ``use_device`` (the intrinsics pass keeps it)."""
    use_device(scene, device)
    cy = scene.cycles
    cy.shading_system = graph == "osl"
    cy.samples = samples
    cy.use_adaptive_sampling = True
    cy.adaptive_threshold = threshold
    cy.max_bounces = cy.diffuse_bounces = cy.glossy_bounces = cy.transmission_bounces = 3
    cy.transparent_max_bounces = 8
    cy.volume_bounces = 0
    cy.seed = 0
    cy.use_animated_seed = False
    cy.use_denoising = True
    cy.denoiser = "OPENIMAGEDENOISE"
    cy.denoising_prefilter = prefilter.upper()
    cy.denoising_quality = quality.upper()
    r = scene.render
    r.resolution_x = r.resolution_y = resolution
    r.resolution_percentage = 100
    r.use_persistent_data = True  # the BVH is built once for all frames
    r.threads_mode = "FIXED"
    r.threads = threads
    r.film_transparent = True  # camera rays that miss the object skip the world shader; the PNG's RGB is black there
    r.use_freestyle = False
    r.use_stamp = False
    scene.view_settings.view_transform = "AgX"
    scene.view_settings.look = "None"


def cycles_record(scene: bpy.types.Scene) -> dict[str, object]:
    """The beauty pass's Cycles settings as Blender holds them, for the manifest: what rendered, read back."""
    cy = scene.cycles
    return {"device": cy.device, "shading_system": "osl" if cy.shading_system else "svm", "samples": cy.samples,
            "adaptive_threshold": round(cy.adaptive_threshold, 6), "denoiser": cy.denoiser,
            "denoising_prefilter": cy.denoising_prefilter, "denoising_quality": cy.denoising_quality,
            "max_bounces": cy.max_bounces}


def probe_world(probe: Path) -> bpy.types.World:
    """The probe lights the object; camera rays see black (background of the dataset)."""
    world = bpy.data.worlds.new("richmat_probe")
    tree = world.node_tree
    tree.nodes.clear()
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(str(probe), check_existing=True)
    lit = tree.nodes.new("ShaderNodeBackground")
    black = tree.nodes.new("ShaderNodeBackground")
    black.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    path = tree.nodes.new("ShaderNodeLightPath")
    mix = tree.nodes.new("ShaderNodeMixShader")
    out = tree.nodes.new("ShaderNodeOutputWorld")
    tree.links.new(env.outputs["Color"], lit.inputs["Color"])
    tree.links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
    tree.links.new(lit.outputs["Background"], mix.inputs[1])
    tree.links.new(black.outputs["Background"], mix.inputs[2])
    tree.links.new(mix.outputs["Shader"], out.inputs["Surface"])
    return world


@contextmanager
def frame_clock() -> Iterator[list[float]]:
    """Seconds of each rendered frame (the first one includes scene sync and OSL setup)."""
    seconds: list[float] = []
    started: list[float] = []

    def pre(*_: object) -> None:
        started.append(time.monotonic())

    def post(*_: object) -> None:
        seconds.append(round(time.monotonic() - started[-1], 3))

    bpy.app.handlers.render_pre.append(pre)
    bpy.app.handlers.render_post.append(post)
    try:
        yield seconds
    finally:
        bpy.app.handlers.render_pre.remove(pre)
        bpy.app.handlers.render_post.remove(post)


def start_azimuth(asset_id: str, seed: int) -> float:
    digest = hashlib.sha256(f"{seed}\0{asset_id}\0camera".encode()).digest()
    return 2 * math.pi * int.from_bytes(digest[:8], "big") / 2.0 ** 64


def orbit(scene: bpy.types.Scene, frames: int, azimuth0: float) -> bpy.types.Object:
    """A closed, smooth orbit: one turn, elevation swinging once up and down, looking at the origin."""
    cam = bpy.data.objects.new("richmat_camera", bpy.data.cameras.new("richmat_camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.data.lens, cam.data.sensor_width, cam.data.sensor_fit = LENS_MM, SENSOR_MM, "HORIZONTAL"
    cam.data.clip_start, cam.data.clip_end = 0.01, 100.0
    half_fov = math.atan(SENSOR_MM / 2 / LENS_MM)
    distance = FRAMING_MARGIN * (math.sqrt(3) / 2) / math.sin(half_fov)
    for i in range(frames):
        t = i / frames
        az = azimuth0 + 2 * math.pi * t
        el = math.radians(ELEVATION_DEG + ELEVATION_SWING_DEG * math.sin(2 * math.pi * t))
        cam.location = distance * Vector((math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)))
        cam.rotation_euler = (-cam.location).to_track_quat("-Z", "Y").to_euler()
        cam.keyframe_insert("location", frame=i)
        cam.keyframe_insert("rotation_euler", frame=i)
    scene.frame_start, scene.frame_end = 0, frames - 1
    return cam


def intrinsics_scene(scene: bpy.types.Scene, samples: int) -> bpy.types.Scene:
    """A copy of ``scene`` (the same objects, camera and orbit) for the cheap SVM pass: AOVs and geometry passes
    only need primary rays, and the maps are unlit, so no world, no bounces, no denoising.

    Its own scene so that Cycles keeps its data across the orbit: kept data belongs to a scene's renderer, and
    in the beauty's scene it would keep the beauty's film. Without it every frame re-syncs the scene (builds
    the BVH, loads every texture) again. The beauty's kept data is freed first."""
    scene.render.use_persistent_data = False  # frees the beauty's kept render data (Blender does so on this switch)
    copy = scene.copy()
    copy.name = "richmat_intrinsics"
    cy = copy.cycles
    cy.shading_system = False
    cy.samples = samples
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.max_bounces = 0
    copy.world = None  # no light to sample: AOVs and geometry passes are unlit
    copy.render.use_persistent_data = True
    return copy


def add_aovs(view_layer: bpy.types.ViewLayer) -> None:
    view_layer.use_pass_normal = True
    view_layer.use_pass_position = True
    for name, kind in AOVS.items():
        aov = view_layer.aovs.add()
        aov.name, aov.type = name, kind


def compositor_outputs(scene: bpy.types.Scene, passes_dir: Path) -> None:
    """Render result to the scene output (beauty), passes and AOVs to one multilayer EXR per frame."""
    tree = bpy.data.node_groups.new("richmat_outputs", "CompositorNodeTree")
    scene.compositing_node_group = tree
    layers = tree.nodes.new("CompositorNodeRLayers")
    layers.scene = scene  # else the context's scene, whose view layer has no such passes
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    group_out = tree.nodes.new("NodeGroupOutput")
    tree.links.new(layers.outputs["Image"], group_out.inputs[0])
    files = tree.nodes.new("CompositorNodeOutputFile")
    files.directory = str(passes_dir) + "/"
    files.file_name = ""
    files.format.media_type = "MULTI_LAYER_IMAGE"
    files.format.file_format = "OPEN_EXR_MULTILAYER"
    files.format.color_depth = "16"
    files.format.exr_codec = "ZIP"
    for name in (*PASSES, *AOVS):
        kind = "VECTOR" if name in PASSES else "FLOAT" if AOVS[name] == "VALUE" else "RGBA"
        files.file_output_items.new(kind, name)
        tree.links.new(layers.outputs[name], files.inputs[name])


def beauty_output(scene: bpy.types.Scene, rgb_dir: Path, file_format: str = "PNG") -> None:
    scene.render.filepath = str(rgb_dir) + "/"
    settings = scene.render.image_settings
    settings.media_type = "IMAGE"
    settings.file_format = file_format
    settings.color_mode = "RGB"
    if file_format == "PNG":
        settings.color_depth = "8"


def scratch_output(scene: bpy.types.Scene, folder: Path) -> None:
    """Where a pass whose own image is not wanted writes it (an animation render writes every frame): BMP with
    the Standard view, the cheapest to write. The compositor's EXRs hold scene values, which no view changes."""
    beauty_output(scene, folder, "BMP")
    scene.view_settings.view_transform = "Standard"


def camera_record(scene: bpy.types.Scene, cam: bpy.types.Object, frames: int) -> dict[str, Any]:
    """Intrinsics (pixels) and per-frame camera-to-world matrices (Blender camera: -Z forward, +Y up)."""
    res = scene.render.resolution_x
    focal_px = cam.data.lens / cam.data.sensor_width * res
    record = {"convention": "Blender/OpenGL camera: looks down -Z, +Y up; world Z up; matrices row-major",
              "intrinsics": {"width": res, "height": scene.render.resolution_y, "fx": focal_px, "fy": focal_px,
                             "cx": res / 2, "cy": scene.render.resolution_y / 2, "lens_mm": cam.data.lens,
                             "sensor_width_mm": cam.data.sensor_width},
              "frames": []}
    for i in range(frames):
        scene.frame_set(i)
        c2w = cam.matrix_world.copy()
        record["frames"].append({"frame": i, "camera_to_world": [list(r) for r in c2w],
                                 "world_to_camera": [list(r) for r in c2w.inverted()]})
    return record


def encode_video(frames_dir: Path, frames: int, fps: int, out: Path, size: tuple[int, int]) -> None:
    """The beauty PNGs (``size`` pixels) as an H.264 MP4 with Blender's own ffmpeg (a sequencer scene)."""
    scene = bpy.data.scenes.new("richmat_video")
    first = sorted(frames_dir.glob("*.png"))[0]
    editor = scene.sequence_editor_create()
    strip = editor.strips.new_image("frames", str(first), 1, 1)
    for path in sorted(frames_dir.glob("*.png"))[1:]:
        strip.elements.append(path.name)
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.fps = fps
    scene.frame_start, scene.frame_end = 1, frames
    scene.view_settings.view_transform = "Standard"  # the PNGs are display values already
    settings = scene.render.image_settings
    settings.media_type = "VIDEO"
    settings.file_format = "FFMPEG"
    scene.render.ffmpeg.format = "MPEG4"
    scene.render.ffmpeg.codec = "H264"
    scene.render.ffmpeg.constant_rate_factor = "HIGH"
    scene.render.filepath = str(out)
    scene.render.use_file_extension = False
    bpy.ops.render.render(animation=True, scene=scene.name)
