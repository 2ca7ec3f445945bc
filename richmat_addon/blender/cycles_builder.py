"""Build a Cycles material (OSL Script node) for an ``EnhancedMaterial``.

The shader text comes from ``core.osl`` for the graph pruned by the material's
constants, so an untextured Type 0 material compiles to a few lines. Every
shader input becomes a Script-node socket: textured parameters are wired to
Image Texture nodes (grouped in one frame per lobe), constants are written as
socket default values.

Colour spaces: our maps are written as linear values. Colour-valued maps
(base colour, conductor reflectivity, scatter colour) are tagged
"Linear Rec.709", so Blender converts them only if the file's working space is
not Rec.709, as for any other colour. Data maps (weights, alphas, IORs) are
"Non-Color": never transformed.
"""
from __future__ import annotations

import os
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator, Union

import bpy

from ..core import graph, osl, schema
from ..core.maps import EnhancedMaterial, ParamMap
from .osl_env import prefer_blender_bundled_modules

SCRIPT_NODE = "richmat_osl"
OUTPUT_NODE = "richmat_output"
COLOR_SPACE_COLOR = "Linear Rec.709"
COLOR_SPACE_DATA = "Non-Color"

# Frame of the base colour texture; parameters go to the frame of their schema lobe group.
_BASE_GROUP = "base"
# Column and row pitch of the texture nodes (left of the Script node).
_TEXTURE_SPACING = (300.0, 280.0)


def enable_osl(scene: bpy.types.Scene) -> None:
    """Cycles on the CPU with OSL: the Script node only runs there (and on OptiX)."""
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.shading_system = True


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


def _inputs_by_group(inputs: list[osl.ShaderInput]) -> dict[str, list[osl.ShaderInput]]:
    groups: dict[str, list[osl.ShaderInput]] = {}
    for inp in inputs:
        param = schema.PARAM_BY_NAME.get(inp.name)
        groups.setdefault(param.lobe if param else _BASE_GROUP, []).append(inp)
    return groups


def _map_of(mat: EnhancedMaterial, name: str) -> ParamMap:
    return mat.base_color if name == "base_color" else mat.params[name]


def _set_constant(socket: bpy.types.NodeSocket, value: ParamMap) -> None:
    v = [float(x) for x in value.value]
    socket.default_value = (*v[:3], 1.0) if socket.type == "RGBA" else v[0]


def build_material(mat: EnhancedMaterial, texture_paths: dict[str, Texture],
                   name: str | None = None, node: graph.Node = graph.SURFACE) -> bpy.types.Material:
    """A Cycles material whose surface is the OSL shader of ``mat``'s pruned graph.

    ``texture_paths`` maps parameter names (and ``"base_color"``) to image files
    or images; it must hold every parameter that is a texture in ``mat``. ``node``
    renders a part of the graph instead (one lobe alone, for agreement tests).
    """
    name = name or mat.name
    material = bpy.data.materials.new(name)
    material.node_tree.nodes.clear()
    try:
        add_enhanced_nodes(material, mat, texture_paths, node)
    except (RuntimeError, KeyError, ValueError):
        bpy.data.materials.remove(material)
        raise
    return material


def add_enhanced_nodes(material: bpy.types.Material, mat: EnhancedMaterial,
                       texture_paths: dict[str, Texture],
                       node: graph.Node = graph.SURFACE) -> bpy.types.ShaderNodeScript:
    """Add the Script node, its textures and a Cycles output to ``material``'s tree.

    Nodes already in the tree stay (the add-on keeps the original normal-map chain
    there); the caller links them. Returns the Script node.
    """
    pruned = graph.prune(node, mat.constants())
    if pruned is None:
        raise ValueError(f"{mat.name}: nothing of the graph is left after pruning its constants")
    inputs = osl.shader_inputs(pruned)
    textured = [i.name for i in inputs if i.name != "Normal" and not _map_of(mat, i.name).is_constant]
    missing = [n for n in textured if n not in texture_paths]
    if missing:
        raise KeyError(f"no texture path for textured parameters {missing}")

    prefer_blender_bundled_modules()  # assigning the script runs Cycles' update, which imports oslquery
    tree = material.node_tree
    text = bpy.data.texts.new(f"{material.name}.osl")
    text.from_string(osl.osl_source(pruned, name="richmat_enhanced"))
    script = tree.nodes.new("ShaderNodeScript")
    script.name, script.label = SCRIPT_NODE, "richmat enhanced (OSL)"
    script.mode = "INTERNAL"
    script.script = text
    script.width = 240
    script.location = (0.0, 0.0)
    try:
        compile_script_node(script)
    except RuntimeError:
        tree.nodes.remove(script)
        bpy.data.texts.remove(text)
        raise

    output = tree.nodes.new("ShaderNodeOutputMaterial")
    output.name = OUTPUT_NODE
    output.target = "CYCLES"
    output.location = (400.0, 0.0)
    tree.links.new(script.outputs["BSDF"], output.inputs["Surface"])

    for inp in inputs:
        if inp.name != "Normal" and inp.name not in textured:
            _set_constant(script.inputs[inp.name], _map_of(mat, inp.name))

    dx, dy = _TEXTURE_SPACING
    row = 0
    for group, members in _inputs_by_group([i for i in inputs if i.name in textured]).items():
        frame = tree.nodes.new("NodeFrame")
        frame.name = f"richmat_frame_{group}"
        frame.label = group
        for inp in members:
            tex = tree.nodes.new("ShaderNodeTexImage")
            tex.name = tex.label = f"tex_{inp.name}"
            tex.image = _load_image(texture_paths[inp.name], color=inp.osl_type == "color")
            tex.parent = frame
            tex.location_absolute = (-2 * dx, -row * dy)
            tree.links.new(tex.outputs["Color"], script.inputs[inp.name])
            row += 1
    return script
