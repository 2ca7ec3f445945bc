"""The Cycles OSL backend: generated shader text, compilation and tiny CPU renders."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from richmat_addon.core import graph, osl, schema
from richmat_addon.core.maps import EnhancedMaterial, ParamMap

TYPE0 = {"haze_weight": 0.3}
COATED = {**TYPE0, "coat_weight": 1.0, "coat_alpha": 0.02}
TYPE5 = {**COATED, "dust_weight": 0.5, "inner_weight": 0.6, "subsurf_weight": 1.0,
         "scatter_color": (0.8, 0.5, 0.3)}


def make_material(name: str, overrides: dict[str, float | tuple[float, ...]],
                  textures: dict[str, np.ndarray] | None = None,
                  base_color: tuple[float, float, float] | np.ndarray = (0.2, 0.2, 0.2)) -> EnhancedMaterial:
    """Schema defaults, overridden by constants and (H, W, C) textures; the enhancer is not needed."""
    params = {p.name: ParamMap.constant(*np.atleast_1d(overrides.get(p.name, p.default)))
              for p in schema.PARAMS}
    params.update({k: ParamMap(v) for k, v in (textures or {}).items()})
    base = ParamMap(base_color) if isinstance(base_color, np.ndarray) else ParamMap.constant(*base_color)
    return EnhancedMaterial(name, type=0, seed=0, base_color=base, params=params)


def write_png(path: Path, value: np.ndarray) -> str:
    """8-bit PNG of a (H, W, C) map in [0, 1], stored without any transfer curve."""
    img = np.round(np.clip(value, 0.0, 1.0) * 255).astype(np.uint8)
    Image.fromarray(img[..., 0] if img.shape[-1] == 1 else img).save(path)
    return str(path)


def test_full_shader_has_one_input_per_parameter():
    inputs = osl.shader_inputs(graph.SURFACE)
    assert [i.name for i in inputs] == ["base_color", *(p.name for p in schema.PARAMS), "Normal"]
    kinds = {i.name: i.osl_type for i in inputs}
    assert kinds["spec_color"] == kinds["scatter_color"] == kinds["base_color"] == "color"
    assert kinds["Normal"] == "normal" and kinds["alpha_core"] == "float"
    src = osl.osl_source()
    for inp in inputs:
        assert inp.declaration() in src
    assert src.count("layer(") == 5 and '"multi_ggx"' in src and "artistic_ior(" in src
    # Sheen colour is a multiplier, never the double-counted albedo argument.
    assert "sheen_bsdf(Nn, color(1)," in src and "scatter_color * sheen_bsdf" in src


def test_pruned_graph_gives_shorter_shader_without_disabled_lobes():
    type0 = make_material("t0", TYPE0)
    src = osl.osl_source(graph.prune(graph.SURFACE, type0.constants()))
    assert len(src) < len(osl.osl_source()) / 2
    for word in ("dust", "coat", "scatter", "inner", "subsurf", "sheen", "conductor", "metalness"):
        assert word not in src, word
    metal = graph.prune(graph.SURFACE, make_material("m", {**TYPE0, "metalness": 1.0}).constants())
    metal_src = osl.osl_source(metal)
    assert "diffuse(" not in metal_src and "base_color" not in metal_src
    assert metal_src.count("artistic_ior(") == 1  # shared by core and haze


# Child-process code shared by the Cycles tests: load materials saved by save_materials,
# set up the preview ball (torch_models.render.preview_scene) and render it tiny on the CPU.
BLENDER_PRELUDE = """
import json, math, time
import numpy as np
import bpy
from richmat_addon.blender.osl_env import prefer_blender_bundled_modules
prefer_blender_bundled_modules()
from richmat_addon.blender import cycles_builder
from richmat_addon.core import graph, osl
from richmat_addon.core.maps import EnhancedMaterial, ParamMap
from torch_models.render.preview_scene import PreviewScene

def load_material(npz, name):
    data = np.load(npz)
    maps = {k.split(".", 1)[1]: ParamMap(data[k]) for k in data.files if k.startswith(name + ".")}
    return EnhancedMaterial(name, 0, 0, maps.pop("base_color"), maps)

def preview_scene(world, sun, size, samples):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    cycles_builder.enable_osl(scene)
    ps = PreviewScene()
    bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=ps.radius)
    bpy.ops.object.shade_smooth()
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    cam.location, cam.rotation_euler = (0.0, -ps.distance, 0.0), (math.pi / 2, 0.0, 0.0)
    cam.data.angle = math.radians(ps.fov_deg)
    scene.collection.objects.link(cam)
    scene.camera = cam
    if sun:
        light = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
        light.data.energy, light.data.angle = 3.0, math.radians(8.0)
        light.rotation_euler = (math.radians(60.0), 0.0, math.radians(-30.0))
        scene.collection.objects.link(light)
    scene.world = bpy.data.worlds.new("uniform")  # Blender 5 worlds always use their nodes
    scene.world.node_tree.nodes["Background"].inputs["Color"].default_value = (*world, 1.0)
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.cycles.samples = samples
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.render.threads_mode, scene.render.threads = "FIXED", 2
    scene.render.image_settings.file_format = "OPEN_EXR"
    return scene

def render(scene, material, name):
    sphere = bpy.data.objects["Sphere"]
    sphere.data.materials.clear()
    sphere.data.materials.append(material)
    scene.render.filepath = f"//{name}.exr"
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(bpy.path.abspath(scene.render.filepath))
    size = scene.render.resolution_x
    px = np.array(img.pixels[:], dtype=np.float32).reshape(size, size, 4)[..., :3]
    np.save(f"{name}.npy", px)
"""


def save_materials(path: Path, materials: dict[str, EnhancedMaterial]) -> str:
    """Hand materials to the child process as one .npz (keys ``material.parameter``)."""
    np.savez(path, **{f"{m}.{k}": v.value for m, mat in materials.items()
                      for k, v in {**mat.params, "base_color": mat.base_color}.items()})
    return str(path)


def test_cycles_compiles_and_renders(blender_run, tmp_path):
    rng = np.random.default_rng(0)
    textures = {"alpha_core": rng.uniform(0.05, 0.3, (4, 4, 1)).astype(np.float32),
                "scatter_color": rng.uniform(0.3, 0.9, (4, 4, 3)).astype(np.float32)}
    base = rng.uniform(0.1, 0.5, (4, 4, 3)).astype(np.float32)
    paths = {k: write_png(tmp_path / f"{k}.png", v) for k, v in {**textures, "base_color": base}.items()}
    materials = {"type0": make_material("type0", TYPE0), "coated": make_material("coated", COATED),
                 "type5": make_material("type5", TYPE5, textures, base)}
    npz = save_materials(tmp_path / "materials.npz", materials)

    result = blender_run(BLENDER_PRELUDE + f"""
out = {{}}
scene = preview_scene(world=(0.2, 0.2, 0.2), sun=True, size=48, samples=16)

# The full graph compiles and gets one socket per shader input.
node = bpy.data.materials.new("full").node_tree.nodes.new("ShaderNodeScript")
node.mode = "INTERNAL"
node.script = bpy.data.texts.new("full.osl")
node.script.from_string(osl.osl_source())
t = time.perf_counter()
cycles_builder.compile_script_node(node)
out["compile_s"] = time.perf_counter() - t
out["sockets"] = [(s.identifier, s.type) for s in node.inputs]
out["outputs"] = [s.identifier for s in node.outputs]
node.script.from_string("shader broken(output closure color BSDF = 0) {{ BSDF = nope(N); }}")
try:
    cycles_builder.compile_script_node(node)
    out["error"] = None
except RuntimeError as exc:
    out["error"] = str(exc)

out["seconds"], out["nodes"] = {{}}, {{}}
for name in {list(materials)!r}:
    t = time.perf_counter()
    bmat = cycles_builder.build_material(load_material({npz!r}, name), {paths!r})
    build_s = time.perf_counter() - t
    nodes = bmat.node_tree.nodes
    script = nodes[cycles_builder.SCRIPT_NODE]
    out["nodes"][name] = {{
        "sockets": [s.identifier for s in script.inputs],
        "textured": sorted(n.name[len("tex_"):] for n in nodes if n.name.startswith("tex_")),
        "frames": sorted(n.label for n in nodes if n.type == "FRAME"),
        "colorspaces": {{n.name: n.image.colorspace_settings.name for n in nodes if n.type == "TEX_IMAGE"}},
        "source": script.script.as_string(),
    }}
    t = time.perf_counter()
    render(scene, bmat, name)
    out["seconds"][name] = {{"build": build_s, "render": time.perf_counter() - t}}
print("RESULT " + json.dumps(out))
""")

    names = [s for s, _ in result["sockets"]]
    assert names == [i.name for i in osl.shader_inputs(graph.SURFACE)]
    assert result["outputs"] == ["BSDF"]
    assert dict(result["sockets"])["spec_color"] == "RGBA" and dict(result["sockets"])["coat_ior"] == "VALUE"
    assert result["error"] is not None and "nope" in result["error"] and "error" in result["error"]

    type5 = result["nodes"]["type5"]
    assert type5["textured"] == ["alpha_core", "base_color", "scatter_color"]
    assert type5["frames"] == ["base", "coat", "dielectric", "dust", "inner", "specular", "subsurf"]
    assert type5["colorspaces"] == {"tex_alpha_core": "Non-Color", "tex_base_color": "Linear Rec.709",
                                    "tex_scatter_color": "Linear Rec.709"}
    type0 = result["nodes"]["type0"]
    assert type0["textured"] == [] and "coat" not in type0["source"]
    assert len(type0["sockets"]) < len(type5["sockets"])

    px = {name: np.load(tmp_path / f"{name}.npy") for name in materials}
    for name, img in px.items():
        assert np.isfinite(img).all(), name
        assert img.mean() > 0.02, name  # the sphere is lit, not black
    # The coat promises a sharp highlight: compare a 3x3 window around the coated peak.
    y, x = np.unravel_index(px["coated"].sum(-1).argmax(), (48, 48))
    window = (slice(max(y - 1, 0), y + 2), slice(max(x - 1, 0), x + 2))
    assert px["coated"][window].mean() > 3 * px["type0"][window].mean()
    # Inner scattering and the tinted subcutaneous lobe warm the silhouette of the Type 5 ball.
    assert not np.allclose(px["type5"], px["coated"], atol=1e-3)


def test_osl_env_refuses_pypi_openimageio_imported_first(blender_run):
    result = blender_run("""
        import json
        import OpenImageIO  # PyPI's build, from the venv
        import bpy
        from richmat_addon.blender.osl_env import prefer_blender_bundled_modules
        try:
            prefer_blender_bundled_modules()
            message = None
        except RuntimeError as exc:
            message = str(exc)
        print("RESULT " + json.dumps(message))
    """)
    assert result is not None and "OpenImageIO was already imported" in result


def test_white_furnace_conserves_energy_in_the_max_channel(blender_run, tmp_path):
    """White base, uniform white world: Cycles' layering gives tops + (1 - max_c(albedo)) * base.

    Every top is white or tinted by scatter_color = (0.8, 0.5, 0.3), so red is the largest
    channel of every top's albedo and must come out at exactly 1. It does not if the sheen
    colour is double counted (layer albedo w c^2 R: brighter) or if the specular lobes are
    single-scatter "ggx" (overestimated albedo: darker base).
    """
    mat = make_material("furnace", {**TYPE5, "alpha_core": 0.5, "inner_weight": 1.0, "inner_roughness": 1.0},
                        base_color=(1.0, 1.0, 1.0))
    npz = save_materials(tmp_path / "materials.npz", {"furnace": mat})
    blender_run(BLENDER_PRELUDE + f"""
scene = preview_scene(world=(1.0, 1.0, 1.0), sun=False, size=32, samples=64)
scene.cycles.max_bounces = 1
render(scene, cycles_builder.build_material(load_material({npz!r}, "furnace"), {{}}), "furnace")
""")
    centre = np.load(tmp_path / "furnace.npy")[12:20, 12:20].reshape(-1, 3).mean(0)
    assert centre[0] == pytest.approx(1.0, abs=0.01)  # "ggx": 0.978, double-counted sheen: 1.05
    assert centre[0] > centre[1] > centre[2]
