"""AgX view transform, applied with Blender's own OpenColorIO configuration.

Blender's AgX is an OCIO view (display "sRGB", view "AgX", scene-linear
Rec.709 in). Rather than re-deriving its matrices, log encoding and curve, we
apply the very config that ships in the ``bpy`` wheel through OpenImageIO's
OCIO support, so our images are tone mapped exactly as Blender saves them.
The config is located without importing bpy (torch_models never does).
"""
from __future__ import annotations

import importlib.util
from functools import lru_cache
from pathlib import Path

import numpy as np

DISPLAY, VIEW, SCENE_LINEAR = "sRGB", "AgX", "Linear Rec.709"


@lru_cache(maxsize=1)
def blender_ocio_config() -> Path:
    spec = importlib.util.find_spec("bpy")
    if spec is None or spec.origin is None:
        raise RuntimeError("AgX needs Blender's colour config: install the bpy module (pip install bpy==5.0.1)")
    root = Path(spec.origin).parent
    found = sorted(root.glob("*/datafiles/colormanagement/config.ocio"))
    if not found:
        raise RuntimeError(f"no colormanagement/config.ocio under {root}")
    return found[-1]


def agx(rgb: np.ndarray) -> np.ndarray:
    """Display-referred sRGB (float in [0, 1]) of scene-linear Rec.709 RGB (..., H, W, 3)."""
    import OpenImageIO as oiio

    src = oiio.ImageBuf(np.ascontiguousarray(rgb, np.float32))
    out = oiio.ImageBufAlgo.ociodisplay(src, DISPLAY, VIEW, SCENE_LINEAR,
                                        colorconfig=str(blender_ocio_config()))
    if out.has_error:
        raise RuntimeError(f"AgX transform failed: {out.geterror()}")
    return np.clip(out.get_pixels(oiio.FLOAT)[..., :3], 0.0, 1.0)


def to_png(display: np.ndarray, path: Path) -> None:
    """Write display-referred RGB as an 8-bit PNG."""
    from PIL import Image

    Image.fromarray((np.clip(display, 0, 1) * 255.0 + 0.5).astype(np.uint8)).save(path)
