"""Build the Blender material of an ``EnhancedMaterial``: the exact OSL graph and the native one.

Both come from the graph pruned by the material's constants, so an untextured
Type 0 material compiles to a few lines of OSL and a few nodes. Every parameter
the graph reads is one node, shared by both graphs: an Image Texture
(``tex_<parameter>``) when it is a texture, a Value or RGB node
(``const_<parameter>``, which the panel edits) when it is a constant. Each
node sits in one frame per lobe group.

Outputs (a Material Output's target decides which engine reads it):

- ``richmat_output``, target Cycles: the OSL Script node (exact; CPU and OptiX only)
  or the native group (any device), whichever ``use_in_cycles`` chose;
- ``richmat_output_eevee``, target EEVEE: the native group, or its EEVEE form where
  EEVEE draws a lobe's node in a way of its own (``richmat_native_eevee``: the sheen);
- ``richmat_output_export``, target All and the active output: a Principled BSDF
  with the values an exporter can write (glTF, USD). Neither engine renders it, because
  each has an output of its own target.

Colour spaces: our maps are written as linear values. Colour-valued maps
(base colour, conductor reflectivity, scatter colour) are tagged
"Linear Rec.709", so Blender converts them only if the file's working space is
not Rec.709, as for any other colour. Data maps (weights, alphas, IORs) are
"Non-Color": never transformed.
"""
from __future__ import annotations

import math
import os
import sys
import tempfile
from collections.abc import Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator, Literal, Union

import bpy

from ..core import graph, osl, schema
from ..core.albedo_fits import f0
from ..core.maps import EnhancedMaterial, ParamMap
from . import native_builder
from .osl_env import prefer_blender_bundled_modules

Graph = Literal["osl", "native"]
GRAPHS: tuple[Graph, ...] = ("osl", "native")
SCRIPT_NODE = "richmat_osl"
NEURAL_SCRIPT_NODE = "richmat_neural_osl"  # the neural preview's Script node, which has the same native fallback
NATIVE_NODE = native_builder.NODE
OUTPUT_NODE = "richmat_output"
EEVEE_OUTPUT_NODE = "richmat_output_eevee"
EXPORT_OUTPUT_NODE = "richmat_output_export"
EXPORT_NODE = "richmat_export"
COLOR_SPACE_COLOR = "Linear Rec.709"
COLOR_SPACE_DATA = "Non-Color"

# Frame of the base colour texture; parameters go to the frame of their schema lobe group.
_BASE_GROUP = "base"
# Column and row pitch of the parameter nodes (left of the shaders).
_PARAMETER_SPACING = (300.0, 280.0)
EXPORT_IOR = 1.5


def _specular_level(ior: float) -> float:
    """Principled's Specular IOR Level that gives, at ``EXPORT_IOR``, the F0 of ``ior``: Blender scales
    F0 by 2 x level. glTF's exporter writes KHR_materials_ior only beside a non-default specular, so the
    F0 travels in KHR_materials_specular instead."""
    return f0(ior) / (2.0 * f0(EXPORT_IOR))


# The export Principled BSDF: socket, the parameters that feed it (the first one the graph reads, else
# the first one's value) and how a value becomes the socket's (a function of the value, given the texture's
# mean when it is a texture). Blender squares the roughnesses; glTF's sheen has no weight, so the dust
# weight is the sheen colour (KHR_materials_sheen's sheenColorFactor).
_EXPORT_SOCKETS: tuple[tuple[str, tuple[str, ...], Callable[[float], float] | None], ...] = (
    ("Base Color", ("base_color", "spec_color"), None), ("Metallic", ("metalness",), None),
    ("Roughness", ("alpha_core",), math.sqrt), ("Specular IOR Level", ("diel_ior",), _specular_level),
    ("Coat Weight", ("coat_weight",), None), ("Coat Roughness", ("coat_alpha",), math.sqrt),
    ("Coat IOR", ("coat_ior",), None), ("Sheen Tint", ("dust_weight",), None),
    ("Sheen Roughness", ("dust_roughness",), None))

def enable_osl(scene: bpy.types.Scene) -> None:
    """Cycles on the CPU with OSL, for renders that are not an artist's scene (benches, tests, the farm)."""
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.shading_system = True


def gpu_backend(scene: bpy.types.Scene) -> str | None:
    """The GPU backend Cycles renders ``scene`` with (CUDA, OPTIX, HIP, METAL, ONEAPI); None on the CPU."""
    if scene.cycles.device == "CPU":
        return None
    cycles = bpy.context.preferences.addons.get("cycles")
    backend = cycles.preferences.compute_device_type if cycles is not None else "NONE"
    return None if backend == "NONE" else backend


def osl_device(scene: bpy.types.Scene) -> bool:
    """Whether Cycles' device for ``scene`` can run OSL: the CPU or OptiX."""
    return gpu_backend(scene) in (None, "OPTIX")


def osl_runs(scene: bpy.types.Scene) -> bool:
    """Whether Cycles, as the scene sets it up, runs Script nodes: OSL on, on the CPU or OptiX."""
    return bool(scene.cycles.shading_system) and osl_device(scene)


def switch_device_line(scene: bpy.types.Scene) -> str:
    """The one line telling the artist what to switch where the device cannot run OSL (the add-on never
    changes the device)."""
    return (f"Cycles renders on {gpu_backend(scene)}, which cannot run OSL: set Render Properties > Device to CPU, "
            "or Preferences > System > Cycles Render Devices to OptiX, then press the button again")


def turn_on_osl(scene: bpy.types.Scene) -> str:
    """Turn on the scene's Open Shading Language option where the device can run it (an undoable scene
    setting, never the engine or the device): the sentence for the report, empty when it was on already.
    Call only where ``osl_device(scene)``."""
    if scene.cycles.shading_system:
        return ""
    scene.cycles.shading_system = True
    return "Turned on Open Shading Language in Render Properties (Ctrl+Z undoes it)"


@contextmanager
def _captured_native_output() -> Iterator[Path]:
    """Redirect the C-level stdout/stderr into a file: oslc prints its errors there, not to Python."""
    with tempfile.NamedTemporaryFile("w+", suffix=".log", delete=False) as log:
        path = Path(log.name)
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    fd = os.open(path, os.O_WRONLY | os.O_TRUNC)
    try:
        os.dup2(fd, 1)
        os.dup2(fd, 2)
        yield path
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for f in (*saved, fd):
            os.close(f)


def compile_script_node(node: bpy.types.ShaderNodeScript) -> None:
    """Compile the node's internal OSL text and create its sockets; raise with oslc's messages."""
    prefer_blender_bundled_modules()
    import cycles.osl  # after the bundled modules: it imports oslquery

    reports: list[str] = []
    with _captured_native_output() as log:
        ok = cycles.osl.update_script_node(
            node, lambda kind, msg: reports.append(f"{'/'.join(sorted(kind))}: {msg}"))
    compiler_output = log.read_text().strip()
    log.unlink()
    if not ok:
        raise RuntimeError(f"OSL compilation of {node.script.name!r} failed:\n{compiler_output}\n"
                           + "\n".join(reports))


# A texture is a file to load or an image already in the .blend (the add-on's previews).
Texture = Union[str, bpy.types.Image]


def _load_image(texture: Texture, color: bool) -> bpy.types.Image:
    image = texture if isinstance(texture, bpy.types.Image) else \
        bpy.data.images.load(str(Path(texture).resolve()), check_existing=True)
    image.colorspace_settings.name = COLOR_SPACE_COLOR if color else COLOR_SPACE_DATA
    return image



def _param_group(name: str) -> str:
    param = schema.PARAM_BY_NAME.get(name)
    return param.lobe if param else _BASE_GROUP


def _map_of(mat: EnhancedMaterial, name: str) -> ParamMap:
    return mat.base_color if name == "base_color" else mat.params[name]


def _parameter_nodes(tree: bpy.types.NodeTree, mat: EnhancedMaterial, inputs: list[osl.ShaderInput],
                     texture_paths: dict[str, Texture]) -> dict[str, bpy.types.NodeSocket]:
    """One node per parameter the graph reads, framed by lobe group; their output sockets by name."""
    groups: dict[str, list[osl.ShaderInput]] = {}
    for inp in inputs:
        groups.setdefault(_param_group(inp.name), []).append(inp)
    dx, dy = _PARAMETER_SPACING
    sources = {}
    row = 0
    for group, members in groups.items():
        frame = tree.nodes.new("NodeFrame")
        frame.name, frame.label = f"richmat_frame_{group}", group
        for inp in members:
            value = _map_of(mat, inp.name)
            color = inp.osl_type == "color"
            if value.is_constant:
                node = tree.nodes.new("ShaderNodeRGB" if color else "ShaderNodeValue")
                node.name = node.label = f"const_{inp.name}"
                v = [float(x) for x in value.value]
                node.outputs[0].default_value = (*v[:3], 1.0) if color else v[0]
            else:
                node = tree.nodes.new("ShaderNodeTexImage")
                node.name = node.label = f"tex_{inp.name}"
                node.image = _load_image(texture_paths[inp.name], color)
            node.parent = frame
            node.location_absolute = (-2 * dx, -row * dy)
            sources[inp.name] = node.outputs[0]
            row += 1
    return sources


def _script_node(tree: bpy.types.NodeTree, name: str, pruned: graph.Node) -> bpy.types.ShaderNodeScript:
    prefer_blender_bundled_modules()  # assigning the script runs Cycles' update, which imports oslquery
    text = bpy.data.texts.new(f"{name}.osl")
    text.from_string(osl.osl_source(pruned, name="richmat_enhanced"))
    script = tree.nodes.new("ShaderNodeScript")
    script.name, script.label = SCRIPT_NODE, "richmat enhanced (OSL)"
    script.mode = "INTERNAL"
    script.script = text
    script.width = 240
    try:
        compile_script_node(script)
    except RuntimeError:
        tree.nodes.remove(script)
        bpy.data.texts.remove(text)
        raise
    return script


def _export_node(tree: bpy.types.NodeTree, mat: EnhancedMaterial,
                 sources: dict[str, bpy.types.NodeSocket]) -> bpy.types.Node:
    """The Principled BSDF exporters read: base, metal, core roughness, F0, coat, dust as sheen.

    Constants are written into its sockets, where exporters read them; textures
    are linked, except where a value must be converted (an exporter reads no math
    node), which takes the texture's mean. Bake rebuilds it, so an edit in the
    panel reaches it there.
    """
    node = tree.nodes.new("ShaderNodeBsdfPrincipled")
    node.name, node.label = EXPORT_NODE, "richmat for exporters (glTF, USD)"
    node.location = (0.0, -1100.0)
    node.inputs["IOR"].default_value = EXPORT_IOR
    for socket, params, convert in _EXPORT_SOCKETS:
        name = next((p for p in params if p in sources), params[0])
        value = _map_of(mat, name)
        if not value.is_constant and convert is None:
            tree.links.new(sources[name], node.inputs[socket])
            continue
        v = [convert(float(x)) if convert else float(x) for x in value.mean()]
        if node.inputs[socket].type == "RGBA":  # a colour, or a grey from one value
            node.inputs[socket].default_value = (*(v * 3)[:3], 1.0)
        else:
            node.inputs[socket].default_value = v[0]
    node.inputs["Sheen Weight"].default_value = 1.0 if "dust_weight" in sources else 0.0
    return node


def _output(tree: bpy.types.NodeTree, name: str, target: str, shader: bpy.types.Node,
            y: float) -> bpy.types.ShaderNodeOutputMaterial:
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    output.name, output.target, output.location = name, target, (500.0, y)
    tree.links.new(shader.outputs[0], output.inputs["Surface"])
    return output


def build_material(mat: EnhancedMaterial, texture_paths: dict[str, Texture], name: str | None = None,
                   node: graph.Node = graph.SURFACE, graphs: Sequence[Graph] = GRAPHS,
                   cycles: Graph = "osl") -> bpy.types.Material:
    """A material whose surface is ``mat``'s pruned graph, as OSL, native nodes or both.

    ``texture_paths`` maps parameter names (and ``"base_color"``) to image files
    or images; it must hold every parameter that is a texture in ``mat``. ``node``
    renders a part of the graph instead (one lobe alone, for agreement tests).
    """
    name = name or mat.name
    material = bpy.data.materials.new(name)
    material.node_tree.nodes.clear()
    try:
        add_enhanced_nodes(material, mat, texture_paths, node, graphs, cycles)
    except (RuntimeError, KeyError, ValueError):
        bpy.data.materials.remove(material)
        raise
    return material


def add_enhanced_nodes(material: bpy.types.Material, mat: EnhancedMaterial, texture_paths: dict[str, Texture],
                       node: graph.Node = graph.SURFACE, graphs: Sequence[Graph] = GRAPHS,
                       cycles: Graph = "osl") -> list[bpy.types.Node]:
    """Add the parameter nodes, the graphs and their outputs to ``material``'s tree.

    With one graph, one output reads it (target Cycles for OSL, All for the native
    graph); with both, Cycles reads ``cycles``'s. Where EEVEE's native graph has a form
    of its own (``native_builder.eevee_differs``), the EEVEE output reads that group
    instead. Nodes already in the tree stay (the add-on keeps the original normal-map
    chain there); the caller links them. Returns the nodes whose Normal input takes the
    normal chain.
    """
    pruned = graph.prune(node, mat.constants())
    if pruned is None:
        raise ValueError(f"{mat.name}: nothing of the graph is left after pruning its constants")
    inputs = [i for i in osl.shader_inputs(pruned) if i.name != "Normal"]
    missing = [i.name for i in inputs if not _map_of(mat, i.name).is_constant and i.name not in texture_paths]
    if missing:
        raise KeyError(f"no texture path for textured parameters {missing}")

    tree = material.node_tree
    shaders: dict[Graph, bpy.types.Node] = {}
    if "osl" in graphs:
        shaders["osl"] = _script_node(tree, material.name, pruned)
    sources = _parameter_nodes(tree, mat, inputs, texture_paths)
    natives: list[bpy.types.Node] = []  # the native group, then EEVEE's where it differs
    if "native" in graphs:
        for eevee in (False, True)[:1 + native_builder.eevee_differs(pruned)]:
            native = tree.nodes.new("ShaderNodeGroup")
            native.name = native_builder.EEVEE_NODE if eevee else NATIVE_NODE
            native.label = f"richmat enhanced (native nodes{', EEVEE' if eevee else ''})"
            native.node_tree = native_builder.material_group(pruned, eevee)
            native.width = 240
            natives.append(native)
        shaders["native"] = natives[0]
        normal = tree.nodes.new("ShaderNodeNewGeometry")
        normal.location = (-300.0, -700.0)
        for native in natives:
            tree.links.new(normal.outputs["Normal"], native.inputs["Normal"])
    takers = [*shaders.values(), *natives[1:]]
    for n, shader in enumerate(takers):
        shader.location = (0.0, -500.0 * n)
        for inp in inputs:
            tree.links.new(sources[inp.name], shader.inputs[inp.name])
    if len(shaders) == 1:
        only, shader = next(iter(shaders.items()))
        _output(tree, OUTPUT_NODE, "CYCLES" if only == "osl" else "ALL", shader, 0.0)
        if len(natives) > 1:
            _output(tree, EEVEE_OUTPUT_NODE, "EEVEE", natives[1], -300.0)
        return takers
    _output(tree, OUTPUT_NODE, "CYCLES", shaders[cycles], 0.0)
    _output(tree, EEVEE_OUTPUT_NODE, "EEVEE", natives[-1], -300.0)
    export = _export_node(tree, mat, sources)
    _output(tree, EXPORT_OUTPUT_NODE, "ALL", export, -600.0).is_active_output = True
    return [*takers, export]


def constant_sockets(material: bpy.types.Material | None) -> dict[schema.Param, bpy.types.NodeSocket]:
    """The output sockets of the material's ``const_<parameter>`` nodes, which hold its constant parameters."""
    nodes = material.node_tree.nodes if material is not None and material.node_tree else []
    return {schema.PARAM_BY_NAME[n.name[len("const_"):]]: n.outputs[0] for n in nodes
            if n.name.startswith("const_") and n.name[len("const_"):] in schema.PARAM_BY_NAME}


def _script_node_of(material: bpy.types.Material) -> bpy.types.Node | None:
    nodes = material.node_tree.nodes if material.node_tree else {}
    return next((nodes[n] for n in (SCRIPT_NODE, NEURAL_SCRIPT_NODE) if n in nodes), None)


def use_in_cycles(material: bpy.types.Material, which: Graph) -> None:
    """Feed the Cycles output from the OSL Script node (enhanced or neural) or the native group;
    both stay in the tree."""
    tree = material.node_tree
    source = _script_node_of(material) if which == "osl" else tree.nodes[NATIVE_NODE]
    tree.links.new(source.outputs[0], tree.nodes[OUTPUT_NODE].inputs["Surface"])


def cycles_graph(material: bpy.types.Material) -> Graph | None:
    """Which graph the Cycles output reads, None for a material without both."""
    nodes = material.node_tree.nodes if material.node_tree else {}
    script = _script_node_of(material)
    if script is None or NATIVE_NODE not in nodes or OUTPUT_NODE not in nodes:
        return None
    links = nodes[OUTPUT_NODE].inputs["Surface"].links
    return "osl" if links and links[0].from_node == script else "native"
