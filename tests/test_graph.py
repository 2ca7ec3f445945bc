"""The graph is the single source of truth: check its structure and pruning."""
from richmat_addon.core import graph, schema


def test_schema_has_22_channels_in_declared_order():
    assert schema.N_CHANNELS == 22
    lo, hi = schema.bounds()
    assert len(lo) == len(hi) == len(schema.default_vector()) == 22
    assert all(a <= b for a, b in zip(lo, hi))


def test_surface_lists_all_eight_lobes_top_to_bottom():
    names = [lobe.name for lobe in graph.iter_lobes(graph.SURFACE)]
    assert names == ["dust", "coat", "cond_core", "cond_haze",
                     "diel_core", "diel_haze", "inner", "subsurf"]


def test_prune_keeps_only_enabled_lobes():
    off = {"dust_weight": 0, "coat_weight": 0, "inner_weight": 0, "subsurf_weight": 0}
    dielectric = graph.prune(graph.SURFACE, {**off, "metalness": 0.0})
    assert [l.name for l in graph.iter_lobes(dielectric)] == ["diel_core", "diel_haze"]
    metal = graph.prune(graph.SURFACE, {**off, "metalness": 1.0, "haze_weight": 0.0})
    assert [l.name for l in graph.iter_lobes(metal)] == ["cond_core"]
    assert not any(isinstance(n, graph.Diffuse) for n in _walk(metal))
    half = graph.prune(graph.SURFACE, {**off, "metalness": 0.5})
    assert isinstance(half, graph.Mix)


def test_no_layer_inside_a_top():
    """Cycles silently drops the outer attenuation when a layer() is nested in a top."""
    for node in _walk(graph.SURFACE):
        if isinstance(node, graph.Layer):
            assert isinstance(node.top, (graph.Lobe, graph.Add))
            tops = [node.top] if isinstance(node.top, graph.Lobe) else node.top.terms
            assert all(t.closure != "conductor" for t in tops)


def _walk(node):
    yield node
    for child in ("top", "base", "fg", "bg"):
        if hasattr(node, child):
            yield from _walk(getattr(node, child))
    if isinstance(node, graph.Add):
        yield from node.terms


def test_material_model_doc_lists_every_parameter_with_its_range():
    """docs/material-model.md is the schema's documentation: keep them in step."""
    from pathlib import Path
    doc = (Path(__file__).resolve().parents[1] / "docs" / "material-model.md").read_text()
    rows = {line.split("|")[1].strip().strip("`"): line for line in doc.splitlines()
            if line.startswith("| `")}
    for p in schema.PARAMS:
        assert p.name in rows, f"{p.name} missing from docs/material-model.md"
        assert f"{p.lo:g}" in rows[p.name] and f"{p.hi:g}" in rows[p.name], p.name
