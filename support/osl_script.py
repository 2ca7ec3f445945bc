"""A material whose surface is an outside OSL shader in a Cycles Script node (the Blender side).

The benches and tests that render OSL not written by the add-on's material builder
(MaterialX's generator, support/mtlx_osl.py; the neural preview shader,
support/neural_ball.py) build it here, in the Blender child process.
"""
from __future__ import annotations

import bpy

from richmat_addon.blender import cycles_builder
from richmat_addon.blender.osl_env import prefer_blender_bundled_modules


def script_material(name: str, source: str, output: str = "out") -> bpy.types.Material:
    """A material whose surface is one Script node (named "Script") compiled from the OSL ``source``,
    its closure output ``output``."""
    prefer_blender_bundled_modules()  # assigning the script runs Cycles' update, which imports oslquery
    material = bpy.data.materials.new(name)
    tree = material.node_tree
    tree.nodes.clear()
    text = bpy.data.texts.new(f"{name}.osl")
    text.from_string(source)
    script = tree.nodes.new("ShaderNodeScript")
    script.mode, script.script = "INTERNAL", text
    cycles_builder.compile_script_node(script)
    surface = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(script.outputs[output], surface.inputs["Surface"])
    return material
