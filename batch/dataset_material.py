"""Blender side: a prepared material as two Cycles materials, one per render pass.

The beauty material is one graph of ``richmat_addon.blender.cycles_builder``:
the exact OSL one, or the native node graph any Cycles device renders.
Cycles does not write Shader AOV outputs when it shades with OSL (checked on
bpy 5.0.1: every AOV reads 0), so the intrinsic maps come from a second,
cheap SVM pass whose material has only AOV outputs: the base colour (the
material's own input, not Cycles' diffuse colour, which is wrong for metals),
both latent textures (Non-Color, never transformed) and a coverage value of 1.
"""
from __future__ import annotations

from pathlib import Path

import bpy

from richmat_addon.blender.cycles_builder import COLOR_SPACE_COLOR, COLOR_SPACE_DATA, Graph, build_material
from richmat_addon.core import material_folder, neural_folder
from richmat_addon.core.maps import EnhancedMaterial


def _aov(tree: bpy.types.NodeTree, name: str) -> bpy.types.Node:
    node = tree.nodes.new("ShaderNodeOutputAOV")
    node.aov_name = name
    node.name = f"aov_{name}"
    return node


def _texture(tree: bpy.types.NodeTree, path: str, colour: bool) -> bpy.types.Node:
    node = tree.nodes.new("ShaderNodeTexImage")
    node.image = bpy.data.images.load(path, check_existing=True)
    node.image.colorspace_settings.name = COLOR_SPACE_COLOR if colour else COLOR_SPACE_DATA
    return node


def _read(folder: Path) -> tuple[EnhancedMaterial, dict[str, str]]:
    """The enhanced material of one prepared material folder and its maps' files by name."""
    baked = material_folder.read(folder)
    return baked.material(), {name: str(path) for name, path in baked.texture_paths.items()}


def _beauty(mat: EnhancedMaterial, paths: dict[str, str], graph: Graph) -> bpy.types.Material:
    return build_material(mat, paths, name=f"richmat_{mat.name}", graphs=(graph,))


def beauty(folder: Path, graph: Graph = "osl") -> bpy.types.Material:
    """The beauty material alone: for a folder the fit has not reached, whose intrinsics have no latents."""
    return _beauty(*_read(folder), graph)


def build(folder: Path, graph: Graph = "osl") -> tuple[bpy.types.Material, bpy.types.Material]:
    """(beauty material, intrinsics material) of one prepared and fitted material folder."""
    mat, paths = _read(folder)
    shaded = _beauty(mat, paths, graph)
    material = bpy.data.materials.new(f"richmat_aov_{mat.name}")
    tree = material.node_tree
    tree.nodes.clear()
    surface = tree.nodes.new("ShaderNodeBsdfDiffuse")  # opaque: without a surface Cycles sees through it
    tree.links.new(surface.outputs["BSDF"], tree.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    base = _aov(tree, "basecolor")
    if "base_color" in paths:
        tree.links.new(_texture(tree, paths["base_color"], colour=True).outputs["Color"], base.inputs["Color"])
    else:
        base.inputs["Color"].default_value = (*mat.base_color.value[:3].tolist(), 1.0)
    neural = neural_folder.read(folder / "neural")
    for i, name in enumerate(("latent_a", "latent_b")):
        node = _aov(tree, name)
        if neural.latent_paths is not None:
            latent = _texture(tree, str(neural.latent_paths[i]), colour=False)
            tree.links.new(latent.outputs["Color"], node.inputs["Color"])
        else:  # a colour socket's own value cannot be negative; latents can
            xyz = tree.nodes.new("ShaderNodeCombineXYZ")
            for axis, value in zip("XYZ", neural.latent[3 * i:3 * i + 3]):
                xyz.inputs[axis].default_value = value
            tree.links.new(xyz.outputs["Vector"], node.inputs["Color"])
    _aov(tree, "coverage").inputs["Value"].default_value = 1.0
    return shaded, material
