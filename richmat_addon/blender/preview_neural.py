"""Preview Neural Material: the fitted latents rendered by the decoder itself, in Cycles.

The material is built like the enhanced one (a copy of the original keeping its
normal and UV chains) around a Script node whose OSL source
``core.neural_osl`` generates from the decoder weights the latents were fitted
against. The shipped hybrid decoder's lobes are Cycles closures, lit like any
material (lamps, shadows, the world); the MLP baseline's lobe is an emission lit
by the scene's world alone (an Environment Texture, or the Background colour).
OSL runs in Cycles on the CPU and OptiX only: the material also holds the baked
enhanced material's native graph, which EEVEE renders, and which Cycles renders
where it cannot run OSL (the add-on's handler switches it, as for enhanced ones).
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import bpy

from ..core import material_folder, neural_folder
from ..core.folder_io import FormatError
from ..core.neural_osl import neural_osl_source
from ..core.neural_encoder import WEIGHTS_FILE
from ..core.tensor_file import read_safetensors
from . import cycles_builder, neural_assets, uplift
from .cycles_builder import (COLOR_SPACE_COLOR, COLOR_SPACE_DATA, EEVEE_OUTPUT_NODE, OUTPUT_NODE,
                             compile_script_node)
from .osl_env import prefer_blender_bundled_modules
from .pbr_source import InputProblem

SCRIPT_NODE = cycles_builder.NEURAL_SCRIPT_NODE
SUFFIX = " (richmat neural)"
SAMPLES = 8  # the MLP baseline: directions per shading point for its lobe's world lighting


def _shader_text(weights: Path, digest: str) -> bpy.types.Text:
    """One generated text per decoder (named by its digest), shared by every neural material."""
    name = f"richmat_neural_{digest[:12]}.osl"
    text = bpy.data.texts.get(name)
    if text is None:
        text = bpy.data.texts.new(name)
        text.from_string(neural_osl_source(read_safetensors(weights)))
    return text


def world_lighting(scene: bpy.types.Scene) -> tuple[str, float, tuple[float, float, float]]:
    """(probe file, rotation about z in radians, colour) of the scene's world, as the shader reads it."""
    world = scene.world
    tree = world.node_tree if world else None
    if tree is None:
        return "", 0.0, (0.05, 0.05, 0.05)
    env = next((n for n in tree.nodes if n.bl_idname == "ShaderNodeTexEnvironment" and n.image), None)
    if env is not None and env.image.source == "FILE" and env.image.packed_file is None:
        rotation = 0.0
        vector = env.inputs["Vector"]
        if vector.is_linked and vector.links[0].from_node.bl_idname == "ShaderNodeMapping":
            rotation = float(vector.links[0].from_node.inputs["Rotation"].default_value[2])
        return str(Path(bpy.path.abspath(env.image.filepath)).resolve()), rotation, (0.0, 0.0, 0.0)
    background = next((n for n in tree.nodes if n.bl_idname == "ShaderNodeBackground"), None)
    if background is None or background.inputs["Color"].is_linked:
        return "", 0.0, (0.05, 0.05, 0.05)
    strength = background.inputs["Strength"].default_value
    return "", 0.0, tuple(strength * c for c in background.inputs["Color"].default_value[:3])


def _image(tree: bpy.types.NodeTree, name: str, file: Path, color: bool, row: int) -> bpy.types.Node:
    node = tree.nodes.new("ShaderNodeTexImage")
    node.name = node.label = f"tex_{name}"
    node.image = bpy.data.images.load(str(file), check_existing=True)
    node.image.colorspace_settings.name = COLOR_SPACE_COLOR if color else COLOR_SPACE_DATA
    node.location = (-500.0, -280.0 * row)
    return node


def add_neural_nodes(material: bpy.types.Material, text: bpy.types.Text, baked: material_folder.MaterialFolder,
                     neural: neural_folder.NeuralFolder, scene: bpy.types.Scene) -> list[bpy.types.Node]:
    """Script node, latent/base/energy textures or constants, and the baked material's native graph
    on the EEVEE output; Cycles reads the Script node where it runs OSL, the native graph elsewhere.
    Returns the nodes taking the normal."""
    fallback = cycles_builder.add_enhanced_nodes(material, baked.material(), {
        name: str(path) for name, path in baked.texture_paths.items()}, graphs=("native",))
    tree = material.node_tree
    if EEVEE_OUTPUT_NODE in tree.nodes:  # EEVEE's own form of the native graph has its output already
        tree.nodes.remove(tree.nodes[OUTPUT_NODE])
    else:
        eevee = tree.nodes[OUTPUT_NODE]
        eevee.name, eevee.target = EEVEE_OUTPUT_NODE, "EEVEE"
    prefer_blender_bundled_modules()  # assigning the script runs Cycles' update, which imports oslquery
    script = tree.nodes.new("ShaderNodeScript")
    script.name, script.label = SCRIPT_NODE, "richmat neural preview (OSL)"
    script.mode, script.script, script.width = "INTERNAL", text, 240
    script.location = (0.0, 500.0)
    compile_script_node(script)
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    output.name, output.target, output.location = OUTPUT_NODE, "CYCLES", (500.0, 300.0)
    cycles_builder.use_in_cycles(material, "osl" if cycles_builder.osl_runs(scene) else "native")

    if neural.latent is not None:  # a constant material: one latent vector
        script.inputs["latent_0"].default_value = neural.latent[:3]
        script.inputs["latent_1"].default_value = neural.latent[3:]
    else:
        for k, file in enumerate(neural.latent_paths):
            latent = _image(tree, f"latent_{k}", file, False, k)
            tree.links.new(latent.outputs["Color"], script.inputs[f"latent_{k}"])
    base_file = baked.texture_paths.get("base_color")
    if base_file is not None:
        base = _image(tree, "base_color", base_file, True, 2)
        tree.links.new(base.outputs["Color"], script.inputs["base_color"])
    else:
        script.inputs["base_color"].default_value = (*baked.map("base_color").value.tolist(), 1.0)
    scale = neural.energy_scale
    if isinstance(scale, Path):
        energy = _image(tree, "energy_scale", scale, False, 3)
        tree.links.new(energy.outputs["Color"], script.inputs["energy_scale"])
    else:
        script.inputs["energy_scale"].default_value = float(scale)
    if "probe" in script.inputs:  # the MLP baseline's shader integrates its lobe from the world itself
        probe, rotation, color = world_lighting(scene)
        script.inputs["probe"].default_value = probe
        script.inputs["probe_rotation"].default_value = rotation
        script.inputs["world_color"].default_value = (*color, 1.0)
        script.inputs["samples"].default_value = SAMPLES
    return [script, *fallback]


def preview(context: bpy.types.Context) -> tuple[list[str], str]:
    """Put the neural preview material in the slots whose enhanced material was fitted; the names, and
    what the artist must know about the render settings (OSL turned on, or what to switch)."""
    weights = neural_assets.decoder_folder(context) / WEIGHTS_FILE
    if not weights.is_file():
        raise InputProblem(f"no decoder weights at {weights}: train them (python -m torch_models "
                           "train-decoder) or set Decoder Weights in Preferences > Add-ons > Richmat")
    digest = hashlib.sha256(weights.read_bytes()).hexdigest()
    plans = [p for p in uplift.plan(context.active_object, context.scene.richmat.all_slots)
             if p.original.richmat.enhanced is not None and p.original.richmat.enhanced.richmat.neural_dir]
    if not plans:
        raise InputProblem("no fitted neural material here: run Fit Neural Material first")
    work = []
    for p in plans:
        enhanced = p.original.richmat.enhanced
        try:
            neural = neural_folder.read(Path(enhanced.richmat.neural_dir))
            baked = material_folder.read(Path(enhanced.richmat.bake_dir))
        except FormatError as exc:
            raise InputProblem(f"{p.original.name}: {exc}") from None
        if neural.decoder_sha256 != digest:
            raise InputProblem(f"{p.original.name}: its latents were fitted against another decoder; "
                               "run Fit Neural Material again")
        work.append((p, baked, neural))
    scene = context.scene
    if scene.render.engine == "CYCLES" and not cycles_builder.osl_device(scene):
        raise InputProblem(f"the neural preview is an OSL shader: {cycles_builder.switch_device_line(scene)}")
    notes = [cycles_builder.turn_on_osl(scene)] if cycles_builder.osl_device(scene) else []
    if scene.render.engine != "CYCLES":
        notes.append(f"{scene.render.engine.replace('BLENDER_', '').title()} shows the baked enhanced material; "
                     "set Render Properties > Render Engine to Cycles to see the decoder"
                     + ("" if cycles_builder.osl_device(scene) else
                        f" ({cycles_builder.switch_device_line(scene)})"))
    text = _shader_text(weights, digest)
    lines = []
    for p, baked, neural in work:
        material = uplift.copy_with_chains(
            p, lambda m: add_neural_nodes(m, text, baked, neural, scene))
        name = p.original.name + SUFFIX
        previous = bpy.data.materials.get(name)
        if previous is not None:
            previous.user_remap(material)
            bpy.data.materials.remove(previous)
        material.name = name
        p.obj.material_slots[p.slot_index].material = material
        lines.append(name)
    return lines, ". ".join(n for n in notes if n)


class RICHMAT_OT_preview_neural(bpy.types.Operator):
    """Render the fitted neural material with an OSL shader that runs the decoder (Cycles on the CPU or OptiX,
    where it turns the scene's Open Shading Language on; EEVEE shows the baked enhanced material)"""

    bl_idname = "richmat.preview_neural"
    bl_label = "Preview Neural Material"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        obj = context.active_object
        material = obj.active_material if obj is not None and obj.type == "MESH" else None
        if material is None:
            cls.poll_message_set("Select a mesh object with a material")
            return False
        enhanced = uplift.original_of(material).richmat.enhanced
        if enhanced is None or not enhanced.richmat.neural_dir:
            cls.poll_message_set("Run Fit Neural Material first")
            return False
        return True

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            lines, settings = preview(context)
        except (InputProblem, OSError, RuntimeError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, (f"{settings}. " if settings else "") + "Neural preview: " + ", ".join(lines)
                    + ". Cycles with OSL renders the decoder (the neural lobe lit by the world only); EEVEE the "
                    "baked enhanced material's native nodes")
        return {"FINISHED"}
