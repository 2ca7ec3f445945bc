"""The preview-ball scene in Cycles, built from ``torch_models.render.preview_scene.PreviewScene``.

The tests and benches build it to compare Cycles with the torch renderer and the preview shaders;
no operator of the add-on does, so it lives here, out of the extension.
The ball is a single point of a point cloud (Cycles renders points as exact
spheres), so its silhouette and normals are those of the torch renderer's
analytic sphere, not of a tessellated mesh. EEVEE draws points as coarse
polyhedra, so for EEVEE the ball switches to a fine smooth-shaded UV sphere. The probe lights the scene through
an Environment Texture (bilinear, equirectangular); the film is transparent, so
the RGB of the saved EXR is the ball over black.
"""
from __future__ import annotations

import math
from pathlib import Path

import bpy

from torch_models.render.preview_scene import PreviewScene

BALL = "richmat_preview_ball"
MESH_SWITCH = "mesh ball"
MESH_SEGMENTS = 256  # around the equator; half as many rings


def _ball_object(radius: float, material: bpy.types.Material | None) -> bpy.types.Object:
    """An object whose geometry nodes make one point of ``radius`` at the origin, or, switched by
    ``use_mesh_ball``, a smooth-shaded UV sphere of that radius."""
    tree = bpy.data.node_groups.new(BALL, "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    points = tree.nodes.new("GeometryNodePoints")
    points.inputs["Count"].default_value = 1
    points.inputs["Radius"].default_value = radius
    sphere = tree.nodes.new("GeometryNodeMeshUVSphere")
    sphere.inputs["Segments"].default_value, sphere.inputs["Rings"].default_value = MESH_SEGMENTS, MESH_SEGMENTS // 2
    sphere.inputs["Radius"].default_value = radius
    smooth = tree.nodes.new("GeometryNodeSetShadeSmooth")
    switch = tree.nodes.new("GeometryNodeSwitch")
    switch.input_type = "GEOMETRY"
    switch.name = MESH_SWITCH
    set_material = tree.nodes.new("GeometryNodeSetMaterial")
    set_material.inputs["Material"].default_value = material
    out = tree.nodes.new("NodeGroupOutput")
    tree.links.new(sphere.outputs["Mesh"], smooth.inputs["Geometry"])
    tree.links.new(points.outputs["Points"], switch.inputs["False"])
    tree.links.new(smooth.outputs["Geometry"], switch.inputs["True"])
    tree.links.new(switch.outputs["Output"], set_material.inputs["Geometry"])
    tree.links.new(set_material.outputs["Geometry"], out.inputs["Geometry"])
    obj = bpy.data.objects.new(BALL, bpy.data.meshes.new(BALL))
    obj.modifiers.new("ball", "NODES").node_group = tree
    return obj


def use_mesh_ball(on: bool) -> None:
    """Draw the ball as a mesh (EEVEE draws a point of a point cloud as a coarse polyhedron) or as the point."""
    bpy.data.node_groups[BALL].nodes[MESH_SWITCH].inputs["Switch"].default_value = on


def _world(probe: Path, rotation_deg: float) -> bpy.types.World:
    world = bpy.data.worlds.new("richmat_probe")
    tree = world.node_tree
    tree.nodes.clear()
    coords = tree.nodes.new("ShaderNodeTexCoord")
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(rotation_deg))
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(str(probe), check_existing=True)
    env.interpolation = "Linear"
    env.projection = "EQUIRECTANGULAR"
    background = tree.nodes.new("ShaderNodeBackground")
    out = tree.nodes.new("ShaderNodeOutputWorld")
    tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    tree.links.new(env.outputs["Color"], background.inputs["Color"])
    tree.links.new(background.outputs["Background"], out.inputs["Surface"])
    # EEVEE (Cycles ignores this): keep the whole probe in the world's light probe. By default EEVEE turns
    # radiance above 10 into a sun, which on this probe left a diffuse ball at 0.37 of Cycles' brightness.
    world.sun_threshold = 0.0
    return world


def setup(scene: bpy.types.Scene, preview: PreviewScene, probe: Path,
          material: bpy.types.Material | None, samples: int, seed: int = 0,
          with_ball: bool = True) -> None:
    """Make ``scene`` the preview scene: camera, ball, probe and converged Cycles settings."""
    cam_data = bpy.data.cameras.new("richmat_preview_camera")
    cam_data.sensor_fit = "AUTO"
    cam_data.angle = math.radians(preview.fov_deg)
    cam = bpy.data.objects.new("richmat_preview_camera", cam_data)
    cam.location = (0.0, -preview.distance, 0.0)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    if with_ball:
        scene.collection.objects.link(_ball_object(preview.radius, material))
    scene.world = _world(probe, preview.probe_rotation_deg)

    scene.render.engine = "CYCLES"
    scene.render.resolution_x = scene.render.resolution_y = preview.resolution
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = with_ball
    scene.view_settings.view_transform = "AgX"
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = samples
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.seed = seed
    # Nothing may bias the estimate: no clamping, no glossy blur.
    cycles.sample_clamp_direct = 0.0
    cycles.sample_clamp_indirect = 0.0
    cycles.blur_glossy = 0.0


def add_sun(scene: bpy.types.Scene, direction: tuple[float, float, float], irradiance: float) -> None:
    """A sun lamp at angle 0 (a delta light, as the torch renderer's ``render.ball.Sun``) shining from
    ``direction`` with ``irradiance`` (Cycles' Strength)."""
    import mathutils

    lamp = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    lamp.data.energy, lamp.data.angle = irradiance, 0.0
    lamp.rotation_mode = "QUATERNION"
    lamp.rotation_quaternion = mathutils.Vector(direction).to_track_quat("Z", "Y")
    scene.collection.objects.link(lamp)


def render_exr(scene: bpy.types.Scene, path: Path) -> None:
    """Render the scene and save scene-linear RGBA as a float EXR."""
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
