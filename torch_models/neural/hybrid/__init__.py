"""The hybrid decoder, the shipped kind: analytic GGX, diffuse and sheen lobes gated by a small network.

Its networks and lobe sampler, its config and kind entry, its closure form (what Cycles renders)
and its free lobe form (how far the lobes themselves reach) live here; the rest of the package
reaches it through its kind entry (``hybrid.kind.KIND``). It never imports the MLP baseline
(``tests/test_layering.py``).
"""
