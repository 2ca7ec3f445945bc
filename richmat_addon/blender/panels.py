"""The "Richmat" sidebar tab, in the 3D Viewport and in the Shader Editor.

Parameters are shown per lobe from the enhanced material's parameter nodes,
which both graphs read: a ``const_<parameter>`` node is a constant the user
edits in place (Bake keeps the edit), a ``tex_<parameter>`` one a texture.
"""
from __future__ import annotations

import bpy

from ..core import schema
from ..core.enhancement_types import TYPES
from ..core.prompt import read_prompt
from . import cycles_builder, fit_error_view, preview_neural, uplift

_LOBE_TITLES = {"dust": "Dust / Fuzz", "coat": "Clearcoat", "conductor": "Conductor", "mix": "Metalness",
                "specular": "Core / Haze", "dielectric": "Dielectric", "inner": "Inner Scattering",
                "subsurf": "Subcutaneous"}


def _enhanced(context: bpy.types.Context) -> bpy.types.Material | None:
    obj = context.active_object
    material = obj.active_material if obj is not None else None
    if material is None:
        return None
    return material if uplift.is_enhanced(material) else material.richmat.enhanced


def draw_richmat(layout: bpy.types.UILayout, context: bpy.types.Context) -> None:
    s = context.scene.richmat
    col = layout.column()
    col.prop(s, "enhancement_type")
    if s.enhancement_type != "AUTO":
        col.label(text=TYPES[int(s.enhancement_type)].description)
    col.prop(s, "amount", slider=True)
    col.prop(s, "seed")
    col.prop(s, "all_slots")
    col.operator("richmat.uplift_material", icon="SHADING_RENDERED")
    col.operator("richmat.switch_material", icon="ARROW_LEFTRIGHT")
    col.operator("richmat.toggle_cycles_graph", icon="NODETREE")
    col.operator("richmat.unwrap_uvs", icon="UV")
    col.separator()
    col.prop(s, "output_dir")
    col.operator("richmat.bake_parameters", icon="RENDER_STILL")
    col.prop(s, "fit_steps")
    col.prop(s, "fit_budget")
    col.operator("richmat.fit_neural", icon="NETWORK_DRIVE")
    draw_fit_error(col, context)
    col.prop(s, "prompt")
    if s.prompt.strip():
        box = col.box()  # what Generate will make of the words, before it runs: a misread shows at once
        for line in read_prompt(s.prompt).lines():
            box.label(text=line)
    col.prop(s, "base_colour")
    col.prop(s, "generate_steps")
    col.operator("richmat.generate_material", icon="MATERIAL")
    col.operator("richmat.preview_neural", icon="HIDE_OFF")
    col.operator("richmat.export_materialx", icon="EXPORT")
    enhanced = _enhanced(context)
    if enhanced is not None:
        draw_parameters(layout, enhanced)


def draw_fit_error(layout: bpy.types.UILayout, context: bpy.types.Context) -> None:
    """Each fitted material's fit error and grade, and the error map toggle."""
    obj = context.active_object
    if obj is None or obj.type != "MESH":
        return
    lines = fit_error_view.readout(obj, context.scene.richmat.all_slots)
    for text, icon in lines:
        layout.label(text=text, icon=icon)
    shown = fit_error_view.showing(obj)
    if lines or shown:
        layout.operator("richmat.show_fit_error", icon="HIDE_ON" if shown else "COLORSET_01_VEC",
                        text="Hide Fit Error Map" if shown else "Show Fit Error Map")


def draw_parameters(layout: bpy.types.UILayout, enhanced: bpy.types.Material) -> None:
    box = layout.box()
    settings = enhanced.richmat
    box.label(text=f"{enhanced.name}: type {settings.type}, seed {settings.seed}, amount {settings.amount:.2f}"
              + (" (less on dark texels)" if settings.auto_touch else ""))
    nodes = enhanced.node_tree.nodes
    if preview_neural.SCRIPT_NODE in nodes:
        box.label(text="Neural preview active (switch to edit parameters)")
        return
    which = cycles_builder.cycles_graph(enhanced)
    if which is not None:
        box.label(text="Cycles: exact OSL shader" if which == "osl" else "Cycles: native nodes", icon="NODETREE")
    constants = cycles_builder.constant_sockets(enhanced)
    by_lobe: dict[str, list[schema.Param]] = {}
    for param in schema.PARAMS:
        if param in constants or f"tex_{param.name}" in nodes:
            by_lobe.setdefault(param.lobe, []).append(param)
    for lobe, params in by_lobe.items():
        sub = box.column(align=True)
        sub.label(text=_LOBE_TITLES.get(lobe, lobe))
        for param in params:
            if param in constants:
                sub.prop(constants[param], "default_value", text=param.name)
            else:
                sub.label(text=f"{param.name}: texture", icon="IMAGE_DATA")
    box.label(text="Lobes with weight 0 are pruned; Uplift again to change the type")


class RICHMAT_PT_view3d(bpy.types.Panel):
    bl_idname = "RICHMAT_PT_view3d"
    bl_label = "Richmat"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Richmat"

    def draw(self, context: bpy.types.Context) -> None:
        draw_richmat(self.layout, context)


class RICHMAT_PT_shader_editor(bpy.types.Panel):
    bl_idname = "RICHMAT_PT_shader_editor"
    bl_label = "Richmat"
    bl_space_type = "NODE_EDITOR"
    bl_region_type = "UI"
    bl_category = "Richmat"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return getattr(context.space_data, "tree_type", "") == "ShaderNodeTree"

    def draw(self, context: bpy.types.Context) -> None:
        draw_richmat(self.layout, context)


CLASSES = (RICHMAT_PT_view3d, RICHMAT_PT_shader_editor)
