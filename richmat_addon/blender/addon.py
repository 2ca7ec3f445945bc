"""Register and unregister every class of the add-on, in dependency order."""
from __future__ import annotations

import bpy

from . import neural_assets, operators, panels, preview_neural, props

_CLASSES = (*props.CLASSES, neural_assets.RichmatPreferences, *operators.CLASSES,
            preview_neural.RICHMAT_OT_preview_neural, *panels.CLASSES)


def register() -> None:
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    props.register()


def unregister() -> None:
    props.unregister()
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
