"""richmat: uplift simple PBR materials to richer layered materials in Blender.

The package is split like glTF-Blender-IO: ``core/`` is host-independent
(pure Python + numpy, importable without bpy or torch) and ``blender/`` holds
everything that imports bpy. Importing this package must not import bpy, so
that the torch backend and the tests can use ``richmat_addon.core`` anywhere;
Blender calls ``register``/``unregister``, which import the bpy side then.
"""


def register() -> None:
    from .blender import addon

    addon.register()


def unregister() -> None:
    from .blender import addon

    addon.unregister()
