"""The layered material model in every renderer that draws it: torch against Cycles (OSL), the native
node graph in Cycles and EEVEE, the MaterialX export, the sheen calibration, the torch evaluator's speed
and the procedural masks (docs/renderer.md, docs/backends.md, docs/lobes.md, docs/enhancement.md)."""
