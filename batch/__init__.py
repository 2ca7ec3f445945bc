"""Farm batch tooling: render the neural-material dataset over Objaverse-style assets.

Two halves that never mix: the orchestrator (``orchestrator``, ``runner``,
``sharding``, ``publish``, ``ledger``, ``assets``, ``options``, ``progress``) is
plain Python and never imports bpy; the per-asset work runs in child processes
(``blender_job`` with bpy, ``python -m torch_models fit`` with torch). Everything
but the fit imports only what a stock Blender 5.0 bundles (docs/batch.md).
"""
