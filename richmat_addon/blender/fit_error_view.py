"""The fit error in the add-on: one number and a word per fitted material in the panel, and the
per-texel error map on the object as a heat-map material that Show Fit Error Map puts in the
slots and takes out again (the material it replaced is kept in ``richmat.shown_over``).

Reads what the torch fit wrote into the neural folder (``core/neural_folder.py``): neural.json
for the number, ``fit_error.exr`` for the map, loaded as an image; no torch, no numpy math.
"""
from __future__ import annotations

from pathlib import Path

import bpy

from ..core import neural_folder
from ..core.fit_error import GRADES, HEAT, POOR
from ..core.folder_io import FormatError
from . import uplift
from .pbr_source import InputProblem

SUFFIX = " (richmat fit error)"
MAP_NODE = "tex_fit_error"  # a tex_ name: copy_with_chains gives it the original textures' UVs
_ICONS = dict(zip(GRADES, ("CHECKMARK", "INFO", "ERROR")))


def _neural(material: bpy.types.Material) -> neural_folder.NeuralFolder | None:
    """The neural folder fitted for the material in a slot (original, enhanced, preview or error map)."""
    enhanced = uplift.original_of(material).richmat.enhanced
    if enhanced is None or not enhanced.richmat.neural_dir:
        return None
    try:
        return neural_folder.read(Path(enhanced.richmat.neural_dir))
    except FormatError:
        return None


def readout(obj: bpy.types.Object, all_slots: bool) -> list[tuple[str, str]]:
    """(line, icon) per fitted material in the slots: its fit error and grade, or why there is none."""
    lines = []
    for index in uplift.slot_indices(obj, all_slots):
        original = uplift.original_of(obj.material_slots[index].material)
        neural = _neural(original)
        if neural is None:
            continue
        error = neural.fit_error
        if error is None:
            lines.append((f"{original.name}: no fit error (encoder or generator only)", "QUESTION"))
        else:
            lines.append((f"{original.name}: fit error {error.mean:.3f}, {error.grade}", _ICONS[error.grade]))
    return lines


def showing(obj: bpy.types.Object) -> bool:
    """Whether some slot of ``obj`` shows a fit error map."""
    return any(s.material is not None and s.material.richmat.shown_over is not None for s in obj.material_slots)


def _heat_nodes(material: bpy.types.Material, error: neural_folder.FitError) -> list[bpy.types.Node]:
    """Error -> colour ramp (green at 0, yellow at GOOD, red from POOR on) -> emission -> output."""
    tree = material.node_tree
    nodes, links = tree.nodes, tree.links
    if error.map is not None:
        source = nodes.new("ShaderNodeTexImage")
        source.name = source.label = MAP_NODE
        source.image = bpy.data.images.load(str(error.map), check_existing=True)
        source.image.reload()
        source.image.colorspace_settings.name = "Non-Color"
        source.interpolation = "Closest"  # texels, not a blend of neighbouring materials' errors
        value = source.outputs["Color"]
    else:
        source = nodes.new("ShaderNodeValue")
        source.outputs[0].default_value = error.mean
        value = source.outputs[0]
    to_unit = nodes.new("ShaderNodeMapRange")
    to_unit.inputs["From Max"].default_value = POOR
    ramp = nodes.new("ShaderNodeValToRGB")
    stops = ramp.color_ramp.elements
    while len(stops) < len(HEAT):
        stops.new(0.5)
    for stop, (at, colour) in zip(stops, HEAT):
        stop.position, stop.color = at / POOR, (*colour, 1.0)
    emission = nodes.new("ShaderNodeEmission")
    output = nodes.new("ShaderNodeOutputMaterial")
    links.new(value, to_unit.inputs["Value"])
    links.new(to_unit.outputs["Result"], ramp.inputs["Fac"])
    links.new(ramp.outputs["Color"], emission.inputs["Color"])
    links.new(emission.outputs["Emission"], output.inputs["Surface"])
    for k, node in enumerate((source, to_unit, ramp, emission, output)):
        node.location = (-900.0 + 300.0 * k, 0.0)
    return []


def show(obj: bpy.types.Object, all_slots: bool) -> list[str]:
    """Put a heat map of the fit error in the slots whose material has one; every check first."""
    work = []
    for p in uplift.plan(obj, all_slots):
        neural = _neural(p.original)
        if neural is not None and neural.fit_error is not None:
            work.append((p, neural.fit_error))
    if not work:
        raise InputProblem("no measured fit error here: run Fit Neural Material with the torch backend first")
    names = []
    for p, error in work:
        slot = obj.material_slots[p.slot_index]
        material = uplift.copy_with_chains(p, lambda m: _heat_nodes(m, error))
        name = p.original.name + SUFFIX
        previous = bpy.data.materials.get(name)
        if previous is not None and previous.users == 0:
            bpy.data.materials.remove(previous)
        material.name = name
        material.richmat.shown_over = slot.material
        slot.material = material
        names.append(f"{p.original.name} ({error.mean:.3f}, {error.grade})")
    return names


def hide(obj: bpy.types.Object) -> list[str]:
    """Put back what the error maps replaced; an error map no slot uses any more is removed."""
    names = []
    for slot in obj.material_slots:
        shown = slot.material
        if shown is None or shown.richmat.shown_over is None:
            continue
        slot.material = shown.richmat.shown_over
        names.append(slot.material.name)
        if shown.users == 0:
            bpy.data.materials.remove(shown)
    return names


class RICHMAT_OT_show_fit_error(bpy.types.Operator):
    """Show each fitted material's per-texel fit error on the object as a heat map (green: good, yellow:
    visible, red: poor); again to put the materials back"""

    bl_idname = "richmat.show_fit_error"
    bl_label = "Show / Hide Fit Error Map"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        obj = context.active_object
        if obj is None or obj.type != "MESH" or obj.active_material is None:
            cls.poll_message_set("Select a mesh object with a material")
            return False
        if not showing(obj) and _neural(obj.active_material) is None:
            cls.poll_message_set("Run Fit Neural Material first")
            return False
        return True

    def execute(self, context: bpy.types.Context) -> set[str]:
        obj = context.active_object
        if showing(obj):
            self.report({"INFO"}, "Fit error map hidden: " + ", ".join(hide(obj)))
            return {"FINISHED"}
        try:
            names = show(obj, context.scene.richmat.all_slots)
        except (InputProblem, OSError, RuntimeError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, "Fit error map (green good, yellow visible, red poor): " + ", ".join(names))
        return {"FINISHED"}
