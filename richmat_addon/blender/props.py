"""Settings the add-on keeps in the .blend: per scene (what to do) and per material (what was done)."""
from __future__ import annotations

import bpy

from ..core.enhancement_types import DIELECTRIC_ONLY, TYPES, index_ranges
from ..core.texel_vectors import FIT_BUDGET

TYPE_ITEMS = [("AUTO", "Auto",
               f"Draw a type from the paper's dataset mix (no {index_ranges(DIELECTRIC_ONLY)} on metals)")] + [
    (str(t.index), f"{t.index}: {t.label}", t.description) for t in TYPES]


class RichmatSceneSettings(bpy.types.PropertyGroup):
    enhancement_type: bpy.props.EnumProperty(
        name="Type", items=TYPE_ITEMS, default="AUTO",
        description="Which lobes the enhancement adds")
    amount: bpy.props.FloatProperty(
        name="Amount", default=1.0, min=0.0, max=1.0, subtype="FACTOR",
        description="How much of the enhancement to apply: 0 gives back the PBR material, 1 the rules as drawn. "
                    "Auto also applies less on dark texels (tyres, dark glass, dark paint), which the rules' "
                    "coat, dust and scatter would turn grey")
    seed: bpy.props.IntProperty(
        name="Seed", default=0, min=0,
        description="Seed of the sampled parameters (mixed with the material name)")
    all_slots: bpy.props.BoolProperty(
        name="All Slots", default=True,
        description="Work on every material slot of the active object, not only the active one")
    output_dir: bpy.props.StringProperty(
        name="Folder", subtype="DIR_PATH", default="",
        description="Where Bake writes parameter maps; empty: a folder next to the .blend file")
    fit_steps: bpy.props.IntProperty(
        name="Fit Steps", default=300, min=1, soft_max=2000,
        description="Optimisation steps of the neural fit")
    fit_budget: bpy.props.IntProperty(
        name="Fit Budget", default=FIT_BUDGET, min=0, soft_max=65536,
        description="Distinct parameter vectors fitted at most: past it, texels share the latents of this many "
                    "representatives, so a photo-scanned texture fits in about a minute; 0 fits every vector "
                    "(a 1k scan: tens of minutes)")
    prompt: bpy.props.StringProperty(
        name="Prompt", default="",
        description="What the generated material looks like: colour, material and finish (\"brushed gold metal\"), "
                    "the enhancement (dust, clear coat, velvet/fuzz, subsurface/waxy) and its strength "
                    "(light, moderate, heavy), e.g. \"red paint with light dust\"")
    base_colour: bpy.props.EnumProperty(
        name="Base", default="AUTO",
        items=[("AUTO", "Auto", "Keep a textured base colour; a material of one colour (a new mesh's default) "
                                "takes the colour, material and finish the prompt names"),
               ("MESH", "Keep the Mesh's", "Keep the material's base colour (roughness and metalness too)"),
               ("WORDS", "From the Prompt", "The colour, material and finish the prompt names, over the material's")],
        description="Where Generate Material's base colour comes from")
    generate_steps: bpy.props.IntProperty(
        name="Sampling Steps", default=18, min=1, soft_max=64,
        description="Diffusion sampling steps of Generate Material (fewer: faster, blurrier)")


class RichmatMaterialSettings(bpy.types.PropertyGroup):
    original: bpy.props.PointerProperty(
        type=bpy.types.Material, name="Original",
        description="The PBR material this enhanced material was made from")
    enhanced: bpy.props.PointerProperty(
        type=bpy.types.Material, name="Enhanced",
        description="The enhanced material made from this one")
    uid: bpy.props.StringProperty(
        name="ID", description="Identifies the material's baked folder so no other material overwrites it")
    type: bpy.props.IntProperty(name="Type", default=-1)
    seed: bpy.props.IntProperty(name="Seed", default=0)
    amount: bpy.props.FloatProperty(name="Amount", default=1.0, min=0.0, max=1.0)
    auto_touch: bpy.props.BoolProperty(name="Auto's Touch", description="Applied less on dark texels (Auto)")
    record: bpy.props.StringProperty(name="Record", description="Enhancement settings (JSON)")
    bake_dir: bpy.props.StringProperty(name="Baked Folder", subtype="DIR_PATH")
    neural_dir: bpy.props.StringProperty(name="Neural Folder", subtype="DIR_PATH")
    shown_over: bpy.props.PointerProperty(
        type=bpy.types.Material, name="Shown Over",
        description="The material a fit error map replaced in the slots; hiding the map puts it back")


CLASSES = (RichmatSceneSettings, RichmatMaterialSettings)


def register() -> None:
    bpy.types.Scene.richmat = bpy.props.PointerProperty(type=RichmatSceneSettings)
    bpy.types.Material.richmat = bpy.props.PointerProperty(type=RichmatMaterialSettings)


def unregister() -> None:
    del bpy.types.Material.richmat
    del bpy.types.Scene.richmat
