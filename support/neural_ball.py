"""The add-on's neural preview shader on the preview scene's ball in Cycles (the Blender side).

bench/addon/closure_preview.py, bench/addon/preview_agreement.py and tests/test_addon_preview.py
render this against the torch renderer: the OSL a decoder's weights generate, in one
Script node, on the ball under the studio probe. They build it here, in the Blender child.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import bpy
import numpy as np

from support import blender_preview_scene
from support.osl_script import script_material
from torch_models.render.preview_scene import PreviewScene


def neural_ball(source: str, probe: Path, resolution: int, spp: int
                ) -> tuple[bpy.types.Scene, bpy.types.ShaderNodeScript]:
    """A fresh scene whose ball's surface is the OSL ``source`` (output ``BSDF``) under ``probe``,
    shaded with OSL, and the Script node whose inputs set the material."""
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    material = script_material("neural", source, output="BSDF")
    blender_preview_scene.setup(scene, PreviewScene(resolution=resolution), probe, material, spp)
    scene.cycles.shading_system = True
    return scene, material.node_tree.nodes["Script"]


def set_material(node: bpy.types.ShaderNodeScript, latent: Sequence[float], base: Sequence[float]) -> None:
    """One material on the ball: its six latents and its base colour."""
    node.inputs["latent_0"].default_value = latent[:3]
    node.inputs["latent_1"].default_value = latent[3:]
    node.inputs["base_color"].default_value = (*base, 1.0)


def read_exr(path: Path) -> np.ndarray:
    """A rendered EXR's RGBA, top row first, (height, width, 4) float32."""
    image = bpy.data.images.load(str(path))
    width, height = image.size
    pixels = np.empty(width * height * 4, np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return pixels.reshape(height, width, 4)[::-1]
