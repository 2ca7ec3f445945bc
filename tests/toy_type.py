"""A seventh enhancement type added to the table alone, run in a child process by test_enhancement_types.

``main`` installs ``enhancement_types.py`` with one more row in ``TYPES`` (Type 6, haze plus scattering
only), as a developer adding a type would edit it, before anything imports it; then it runs the
enhancement, the captions and prompts, the farm's plan and caption, and the generator's conditioning
on that table and prints what they did as ``RESULT <json>`` for the test to judge. Only the standard
library is imported before the table is in place.
"""
from __future__ import annotations

import ast
import importlib.abc
import importlib.machinery
import importlib.util
import json
import sys
import tempfile
from pathlib import Path
from types import ModuleType

TABLE = "richmat_addon.core.enhancement_types"
TOY = 6
TOY_ROW = (f'EnhancementType({TOY}, "Scattering", "Scattering: haze plus inner and subcutaneous scattering", '
           '("scatter",), 0.1, guidance=1.25, metal_remap=0)')


def with_toy_row(source: str) -> str:
    """``source`` with ``TOY_ROW`` appended to the ``TYPES`` tuple literal."""
    node = next(n for n in ast.parse(source).body
                if isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name) and n.target.id == "TYPES")
    assert isinstance(node.value, ast.Tuple)
    last = node.value.elts[-1]
    data = source.encode()  # ast offsets count UTF-8 bytes
    at = sum(len(line) for line in data.splitlines(keepends=True)[:last.end_lineno - 1]) + last.end_col_offset
    return (data[:at] + b", " + TOY_ROW.encode() + data[at:]).decode()


class _ToyTable(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Imports the table module from its own file with the toy row added."""

    def find_spec(self, name: str, path, target=None):  # type: ignore[no-untyped-def]
        if name != TABLE:
            return None
        spec = importlib.machinery.PathFinder.find_spec(name, path)
        return importlib.util.spec_from_loader(name, self, origin=spec.origin)

    def create_module(self, spec):  # type: ignore[no-untyped-def]
        return None

    def exec_module(self, module: ModuleType) -> None:
        origin = module.__spec__.origin
        exec(compile(with_toy_row(Path(origin).read_text(encoding="utf-8")), origin, "exec"), module.__dict__)


def _enhancement() -> dict:
    from richmat_addon.core.enhance import enhance, resolve_type
    from richmat_addon.core.maps import ParamMap, PbrInputs

    plastic = PbrInputs("plastic", ParamMap.constant(0.6, 0.2, 0.2), ParamMap.constant(0.4), ParamMap.constant(0.0))
    metal = PbrInputs("metal", ParamMap.constant(0.9, 0.9, 0.9), ParamMap.constant(0.3), ParamMap.constant(1.0))
    made = enhance(plastic, TOY, seed=1)
    auto = [resolve_type(PbrInputs(f"m{i}", plastic.base_color, plastic.roughness, plastic.metalness), "auto", 0)[0]
            for i in range(2000)]
    return {"settings": made.settings, "type": made.type,
            "params": {k: float(v.value.mean()) for k, v in made.params.items()},
            "on_metal": list(resolve_type(metal, TOY, 0)), "auto_share": auto.count(TOY) / len(auto)}


def _words(settings: dict) -> dict:
    from richmat_addon.core.captions import caption, enhancement_keywords
    from richmat_addon.core.prompt import prompt_type

    words = enhancement_keywords(settings)
    return {"keywords": words, "caption": caption("Candle", [{"name": "Wax", "metallic": False,
                                                              "mean_base_color": [0.6, 0.2, 0.2],
                                                              "settings": settings}]),
            "prompt": list(prompt_type("a waxy candle")), "caption_as_prompt": list(prompt_type(", ".join(words))),
            "prompt_on_metal": list(prompt_type("a waxy candle", metallic=True))}


def _farm(settings: dict, folder: Path) -> dict:
    """batch's plan for assets (the prepare stage's ``--type``) and the caption it publishes for an asset
    whose prepare stage enhanced one material with the toy type."""
    from batch import pipeline, publish
    from batch.assets import Asset, asset_id
    from batch.options import build_parser, settings_of
    from torch_models.assets.enhancement_plan import material_type

    (folder / "in").mkdir()
    (folder / "decoder").mkdir()
    (folder / "decoder" / "weights.safetensors").write_bytes(b"stand-in")
    (folder / "probe.exr").write_bytes(b"stand-in")
    args = build_parser().parse_args(["--input", str(folder / "in"), "--output", str(folder / "out"),
                                      "--decoder", str(folder / "decoder"), "--probe", str(folder / "probe.exr")])
    run = settings_of(args)
    job = pipeline.Job(run, run.hash(), folder / "out", args.probe, args.decoder, 1.0, 0, 1, 1,
                       pipeline.Commands("blender", "python"))
    planned = []
    for i in range(1000):
        path = folder / "in" / f"asset{i}.glb"
        path.write_bytes(b"stand-in asset")
        asset = Asset(path, path.name, asset_id(path.name))
        prepare = dict(pipeline._stage_commands(asset, job, folder))["prepare"]
        planned.append(int(prepare[prepare.index("--type") + 1]))
    asset = Asset(path, path.name, asset_id(path.name))
    work = publish.partial_dir(job.output, asset.id)
    work.mkdir(parents=True)
    material = {"name": "Wax", "metallic": False, "mean_base_color": [0.6, 0.2, 0.2], "settings": settings}
    (work / "asset.json").write_text(json.dumps({"type": TOY, "materials": [material]}))
    (work / "render.json").write_text(json.dumps({}))
    (work / "fit.json").write_text(json.dumps({}))
    manifest = pipeline._manifest(asset, job, {}, 1)
    return {"planned_share": planned.count(TOY) / len(planned), "metal_material": list(material_type(TOY, True)),
            "caption": (work / "caption.txt").read_text(encoding="utf-8").strip(),
            "manifest_type": manifest["enhancement_type"]}


def _generator() -> dict:
    import torch

    from torch_models.generator import guidance_for
    from torch_models.generator.dit import CONDITION_CHANNELS, Conditions, DitConfig, LatentGenerator
    from torch_models.generator.generate import load_generator

    torch.manual_seed(0)
    cfg = DitConfig(size=8, patch=4, dim=16, depth=1, heads=2, text_dim=4)
    model = LatentGenerator(cfg)
    views = torch.ones(1, 1, CONDITION_CHANNELS, cfg.size, cfg.size)
    cond = Conditions(views, torch.ones(1, cfg.text_dim), torch.tensor([TOY]))
    sampled = model.sample(cond, steps=1, seed=0, guidance=2.0)
    shipped, _ = load_generator()
    try:
        shipped.sample(Conditions(torch.ones(1, 1, CONDITION_CHANNELS, 32, 32), torch.ones(1, 384),
                                  torch.tensor([TOY])), steps=1, seed=0)
        refused = ""
    except ValueError as error:
        refused = str(error)
    return {"types": cfg.types, "null_type": model.null_type, "rows": model.net.type_embed.num_embeddings,
            "unconditional": cond.unconditional(model.null_type).type.tolist(), "sampled": list(sampled.shape),
            "guidance": guidance_for(TOY), "shipped_types": shipped.null_type, "shipped_refuses": refused}


def main() -> None:
    sys.meta_path.insert(0, _ToyTable())
    from richmat_addon.core import enhancement_types

    result: dict = {"types": [t.index for t in enhancement_types.TYPES]}
    result["enhancement"] = _enhancement()
    settings = result["enhancement"]["settings"]
    result["words"] = _words(settings)
    with tempfile.TemporaryDirectory() as folder:
        result["farm"] = _farm(settings, Path(folder))
    result["generator"] = _generator()
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
