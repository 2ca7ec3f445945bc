"""A material whose surface is an outside OSL shader in a Cycles Script node (the Blender side).

The benches and tests that render OSL not written by the add-on (MaterialX's
generator, support/mtlx_osl.py) build it here, in the Blender child process.
"""
from __future__ import annotations

import bpy

from richmat_addon.blender import cycles_builder
from richmat_addon.blender.osl_env import prefer_blender_bundled_modules


def script_material(name: str, source: str) -> bpy.types.Material:
    """A material whose surface is one Script node compiled from the OSL ``source``, output ``out``."""
    prefer_blender_bundled_modules()  # assigning the script runs Cycles' update, which imports oslquery
    material = bpy.data.materials.new(name)
    tree = material.node_tree
    tree.nodes.clear()
    text = bpy.data.texts.new(f"{name}.osl")
    text.from_string(source)
    script = tree.nodes.new("ShaderNodeScript")
    script.mode, script.script = "INTERNAL", text
    cycles_builder.compile_script_node(script)
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(script.outputs["out"], output.inputs["Surface"])
    return material
