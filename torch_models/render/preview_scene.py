"""The preview-ball scene, as data shared by the torch renderer and Cycles.

Both renderers build their camera and sphere from this one description, so an
agreement test compares materials, not two slightly different cameras. Cycles' copy
(``support/blender_preview_scene.py``) is built by the tests and benches, inside Blender:
this module and its package import no torch.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class PreviewScene:
    """A unit sphere at the origin seen by a square perspective camera.

    The camera sits at (0, -distance, 0) looking along +y with +z up (Blender's
    front view), which is Blender rotation (90 deg, 0, 0). World +z is up for the
    environment probe, which is rotated by ``probe_rotation_deg`` about +z.
    """

    resolution: int = 256
    distance: float = 4.0
    fov_deg: float = 34.0
    radius: float = 1.0
    probe_rotation_deg: float = 0.0
