"""richmat's torch backend: BRDF, enhancement data, neural material, renderer.

Never imports bpy. Shares the material definition with the add-on through
``richmat_addon.core`` (pure Python + numpy).
"""
