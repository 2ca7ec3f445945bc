"""Register and unregister every class of the add-on, in dependency order, and its two handlers."""
from __future__ import annotations

import bpy
from bpy.app.handlers import persistent

from . import fit_error_view, neural_assets, operators, panels, preview_neural, props, uplift

_CLASSES = (*props.CLASSES, neural_assets.RichmatPreferences, *operators.CLASSES,
            preview_neural.RICHMAT_OT_preview_neural, fit_error_view.RICHMAT_OT_show_fit_error, *panels.CLASSES)
_checked: list[tuple[str, int]] = []  # (graph Cycles can run, materials in the file) at the last check


@persistent
def _keep_cycles_renderable(scene: bpy.types.Scene, *_: object) -> None:
    """When Cycles can no longer run OSL (device, OSL switch) or materials come in, point the enhanced
    materials Cycles reads as OSL at their native graph: a Script node renders black without OSL."""
    state = (uplift.cycles_choice(scene), len(bpy.data.materials))
    if _checked == [state]:
        return
    _checked[:] = [state]
    switched = uplift.keep_cycles_renderable(scene)
    if switched:
        print(f"richmat: Cycles cannot run OSL here; it now renders the native nodes of {', '.join(switched)}")


@persistent
def _on_load(*_: object) -> None:
    _checked.clear()
    if bpy.context.scene is not None:
        _keep_cycles_renderable(bpy.context.scene)


def register() -> None:
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    props.register()
    bpy.app.handlers.depsgraph_update_post.append(_keep_cycles_renderable)
    bpy.app.handlers.load_post.append(_on_load)


def unregister() -> None:
    bpy.app.handlers.load_post.remove(_on_load)
    bpy.app.handlers.depsgraph_update_post.remove(_keep_cycles_renderable)
    props.unregister()
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
