"""The asset and dataset formats the torch backend shares with the farm: glTF files (container, materials,
meshes), the dataset index of a farm output, and the plan that draws each asset's enhancement type.

They live under ``torch_models`` because the add-on never reads them, so they stay out of its package
and of the extension a user installs. They stay torch-free (standard library and numpy, with
``richmat_addon.core`` below them) because the farm's Blender side (``batch/gltf_import.py``,
``batch/bl_scene.py``, ``batch/blender_job.py``) imports them in a stock Blender, which has no torch.
"""
