"""The closure registry: a toy kind added through the tables alone reaches every backend, and leaves no trace.

``tests/toy_closure.py`` holds the toy's halves; nothing of the backends is edited. Torch evaluates
it (a furnace with a closed form), the OSL writer emits it and Blender's oslc compiles the shader,
the MaterialX document validates, and the native builder makes its node group in bpy.
"""
from __future__ import annotations


import pytest
import torch

from richmat_addon.core import graph, mtlx, osl
from richmat_addon.core.closures import KINDS
from tests import toy_closure
from tests.closure_support import F64, direction, hemisphere_rule, scalar
from tests.test_osl import make_material
from torch_models.brdf.closures import TORCH
from torch_models.brdf.model import LayeredBsdf

WEIGHT, COLOUR, BASE = 0.5, (0.8, 0.4, 0.2), 0.6


def test_every_shipped_kind_has_all_its_halves() -> None:
    kinds = set(KINDS.names())
    assert {"sheen", "dielectric", "conductor", "diffuse"} <= kinds
    assert set(TORCH.names()) == kinds
    used = {lobe.closure for lobe in graph.iter_lobes(graph.SURFACE)} | {graph.Diffuse.closure}
    assert used == kinds
    for lobe in graph.iter_lobes(graph.SURFACE):
        assert set(lobe.inputs) == set(KINDS[lobe.closure].inputs), lobe.name


def test_an_unknown_kind_names_the_floor_that_lacks_it() -> None:
    with pytest.raises(KeyError, match="toy_lambert.*no core implementation"):
        osl.osl_source(toy_closure.GRAPH)
    with toy_closure.registered():
        with pytest.raises(KeyError, match="no torch implementation"):
            LayeredBsdf({"dust_weight": scalar(WEIGHT), "scatter_color": torch.tensor([COLOUR], dtype=F64)},
                        torch.full((1, 3), BASE, dtype=F64), node=toy_closure.GRAPH).eval(
                direction(0.5)[None], direction(0.7, 1.0)[None])
        with pytest.raises(ValueError, match="already has a core implementation"):
            KINDS.register(toy_closure.NAME, toy_closure.CORE)


def test_torch_evaluates_the_toy_kind() -> None:
    with toy_closure.registered(torch_floor=True):
        bsdf = LayeredBsdf({"dust_weight": scalar(WEIGHT), "scatter_color": torch.tensor([COLOUR], dtype=F64)},
                           torch.full((1, 3), BASE, dtype=F64), node=toy_closure.GRAPH)
        dirs, weights = hemisphere_rule(64, 64)
        wi = direction(0.6, 0.2).expand_as(dirs)
        total = (bsdf.eval(wi, dirs) * weights).sum(0)
        transmission = float(bsdf.transmission(wi[:1]))
        pdf_total = float((bsdf.pdf(wi, dirs)[:, None] * weights).sum())
    # A Lambertian top reflects w c and lets 1 - max_c(w c) through to the base: the layer rule.
    assert transmission == pytest.approx(1.0 - WEIGHT * max(COLOUR))
    want = WEIGHT * torch.tensor(COLOUR, dtype=F64) + (1.0 - WEIGHT * max(COLOUR)) * BASE
    assert torch.allclose(total, want, atol=1e-6)
    assert pdf_total == pytest.approx(1.0, abs=1e-6)
    assert toy_closure.NAME not in TORCH and toy_closure.NAME not in KINDS  # the registration is gone


def test_materialx_authors_the_toy_kind_and_the_document_validates() -> None:
    mat = make_material("toy", {"dust_weight": WEIGHT, "scatter_color": COLOUR})
    with toy_closure.registered():
        doc = mtlx.to_materialx(mat, {}, surface=toy_closure.GRAPH)
    assert mtlx.validate_document(doc) == []
    toy = doc.getNode("toy")
    assert toy.getCategory() == "oren_nayar_diffuse_bsdf"
    assert toy.getInputValue("weight") == pytest.approx(WEIGHT * max(COLOUR))  # colour normalised into the weight
    assert list(toy.getInputValue("color")) == pytest.approx([c / max(COLOUR) for c in COLOUR])
    layer = next(n for n in doc.getNodes() if n.getCategory() == "layer")
    assert layer.getConnectedNode("top").getName() == "toy"


OSL_AND_NATIVE = """
import json
import bpy
from richmat_addon.blender.osl_env import prefer_blender_bundled_modules
prefer_blender_bundled_modules()
from richmat_addon.blender import cycles_builder, native_builder
from tests import toy_closure

bpy.ops.wm.read_factory_settings(use_empty=True)
out = {}
node = bpy.data.materials.new("toy").node_tree.nodes.new("ShaderNodeScript")
node.mode = "INTERNAL"
node.script = bpy.data.texts.new("toy.osl")
node.script.from_string(SOURCE)
cycles_builder.compile_script_node(node)
out["sockets"] = [s.identifier for s in node.inputs]
with toy_closure.registered(native_floor=True):
    tree = native_builder.material_group(toy_closure.GRAPH)
out["groups"] = sorted(n.node_tree.name for n in tree.nodes if n.type == "GROUP")
family = bpy.data.node_groups["richmat toy lambert v1"]
out["family_nodes"] = sorted(n.bl_idname for n in family.nodes)
out["links_valid"] = all(link.is_valid for t in (tree, family) for link in t.links)
print("RESULT " + json.dumps(out))
"""


def test_osl_compiles_and_the_native_builder_builds_the_toy_kind(blender_run) -> None:
    with toy_closure.registered():
        source = osl.osl_source(toy_closure.GRAPH, name="toy")
        inputs = [i.name for i in osl.shader_inputs(toy_closure.GRAPH)]
    assert "closure color lobe_toy = dust_weight * scatter_color * diffuse(Nn);" in source
    assert "BSDF = layer(lobe_toy, lobe_diffuse);" in source
    result = blender_run(f"SOURCE = {source!r}\n" + OSL_AND_NATIVE)
    assert result["sockets"] == inputs == ["base_color", "dust_weight", "scatter_color", "Normal"]
    assert result["groups"] == ["richmat layer v1", "richmat toy lambert v1"]
    assert "ShaderNodeBsdfDiffuse" in result["family_nodes"] and result["links_valid"]
