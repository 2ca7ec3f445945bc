"""Uplift: a Principled BSDF material to its enhanced twin, next to the original.

The original material is never modified. Its copy keeps the normal-map chain
(and the texture-coordinate nodes of the textures) unchanged and gets both graphs
of ``cycles_builder`` (the exact OSL Script node and the native node group), fed
by parameter maps that ``core.enhance``
computes from the original's pixels at a preview resolution (numpy, no
per-pixel Python); Bake recomputes them at the inputs' full resolution.
Re-running replaces the previous enhanced copy (``user_remap``), so slots,
objects and the undo stack see one material per original.
"""
from __future__ import annotations

import json
import uuid
from dataclasses import dataclass
from typing import Any, Callable

import bpy
import numpy as np

from ..core.enhance import enhance, resolve_type
from ..core.enhancement_types import DUST_TYPES, METAL_TYPES, index_ranges
from ..core.maps import EnhancedMaterial, ParamMap, PbrInputs
from ..core.prompt import Reading, base_over, keeps_base, read_prompt
from . import cycles_builder, mesh_maps
from .pbr_source import InputProblem, PbrSources, load_pbr, read_sources

PREVIEW_SIZE = 512  # longest side of the maps uplift makes (interactive); Bake writes full size
SUFFIX = " (richmat)"
_KEEP_FRAME = "richmat_frame_original"


@dataclass
class SlotPlan:
    """One material slot that passed every check, with what uplift needs."""

    obj: bpy.types.Object
    slot_index: int
    original: bpy.types.Material
    sources: PbrSources


def original_of(material: bpy.types.Material) -> bpy.types.Material:
    return material.richmat.original if material.richmat.original is not None else material


def is_enhanced(material: bpy.types.Material | None) -> bool:
    return material is not None and material.richmat.original is not None


def slot_indices(obj: bpy.types.Object, all_slots: bool) -> list[int]:
    if all_slots:
        return [i for i, slot in enumerate(obj.material_slots) if slot.material is not None]
    return [obj.active_material_index] if obj.active_material is not None else []


def plan(obj: bpy.types.Object, all_slots: bool) -> list[SlotPlan]:
    """Check every slot first: a problem anywhere raises before anything changes."""
    if obj is None or obj.type != "MESH":
        raise InputProblem("select a mesh object")
    if obj.library is not None or obj.data.library is not None:
        raise InputProblem(f"{obj.name!r} is linked from a library; make it local first "
                           "(Object > Relations > Make Local)")
    indices = slot_indices(obj, all_slots)
    if not indices:
        raise InputProblem(f"{obj.name!r} has no material")
    plans = []
    for index in indices:
        original = original_of(obj.material_slots[index].material)
        if original.library is not None:
            raise InputProblem(f"material {original.name!r} is linked from {original.library.filepath}; "
                               "make it local first (Object > Relations > Make Local)")
        sources = read_sources(original)
        if sources.textured and not mesh_maps.has_uvs(obj):
            raise InputProblem(f"{obj.name!r} has textures but no UV map; unwrap it first "
                               "(Richmat > Unwrap UVs)")
        plans.append(SlotPlan(obj, index, original, sources))
    return plans


def enhance_slot(p: SlotPlan, requested: str, seed: int, max_size: int | None, amount: float = 1.0,
                 touch: bool | None = None, words: dict[str, str] | None = None) -> EnhancedMaterial:
    """The enhanced maps of one slot, scaled by ``amount`` and, for Auto (or ``touch``), by the lighter
    touch on dark texels (``core.enhance.auto_touch``); dust types get world maps rasterised from the mesh.
    ``words`` ({"prompt", "base"}: Generate's) put the prompt's base material on the slot where ``base``
    says (``prompt.keeps_base``) and fix the settings its strength words name."""
    pbr = load_pbr(p.sources, max_size)
    fixed = None
    if words:
        reading = read_prompt(words["prompt"])
        pbr = with_words_base(pbr, reading, words["base"])
        fixed = reading.settings()
    type_, note = resolve_type(pbr, "auto" if requested == "AUTO" else int(requested), seed)
    if requested != "AUTO" and type_ != int(requested):
        raise InputProblem(f"{note}; choose a type in {index_ranges(METAL_TYPES)} or Auto for metals")
    normals = positions = None
    size = _texture_size(pbr)
    if type_ in DUST_TYPES and size is not None and mesh_maps.has_uvs(p.obj):
        normals, positions, _ = mesh_maps.world_maps([(p.obj, [p.slot_index])], size)
    return enhance(pbr, type_, seed, world_normals=normals, world_positions=positions, amount=amount,
                   touch=requested == "AUTO" if touch is None else touch, fixed=fixed)


def with_words_base(pbr: PbrInputs, reading: Reading, choice: str) -> PbrInputs:
    """``pbr`` with the base material the prompt names put on (``prompt.base_over``); Blender's
    Principled BSDF always says its roughness and metalness, so the words replace them only where the
    base colour is the words' too."""
    maps = (pbr.base_color, pbr.roughness, pbr.metalness)
    values = base_over(reading, *(m.value for m in maps), keep=keeps_base(pbr.base_color.value, choice))
    base, rough, metal = (m if v is m.value else ParamMap.constant(*np.ravel(v)) for m, v in zip(maps, values))
    return PbrInputs(pbr.name, base, rough, metal)


def _texture_size(pbr: PbrInputs) -> tuple[int, int] | None:
    shapes = [m.shape for m in (pbr.base_color, pbr.roughness, pbr.metalness) if m.shape]
    return max(shapes, key=lambda s: s[0] * s[1]) if shapes else None


def preview_image(name: str, pmap: ParamMap) -> bpy.types.Image:
    """A packed float image holding one map (grey for one channel), bottom row first."""
    h, w = pmap.shape
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = pmap.value if pmap.channels == 3 else pmap.value[..., :1]
    image = bpy.data.images.new(name, w, h, alpha=False, float_buffer=True)
    image.pixels.foreach_set(np.ascontiguousarray(rgba[::-1]).ravel())
    image.pack()
    return image


def _upstream_nodes(socket: bpy.types.NodeSocket) -> set[str]:
    names: set[str] = set()
    stack = [link.from_node for link in socket.links]
    while stack:
        node = stack.pop()
        if node.name not in names:
            names.add(node.name)
            stack.extend(link.from_node for s in node.inputs for link in s.links)
    return names


def _link_source(socket: bpy.types.NodeSocket) -> tuple[str, str] | None:
    """(node name, output identifier) of what feeds a socket, to relink it in the copy."""
    if not socket.is_linked:
        return None
    link = socket.links[0]
    return link.from_node.name, link.from_socket.identifier


def _output(tree: bpy.types.NodeTree, source: tuple[str, str]) -> bpy.types.NodeSocket:
    node = tree.nodes[source[0]]
    return next(s for s in node.outputs if s.identifier == source[1])


def copy_with_chains(p: SlotPlan, add_nodes: Callable[[bpy.types.Material], list[bpy.types.Node]]
                     ) -> bpy.types.Material:
    """The original's copy with only its normal and UV chains kept, plus the nodes ``add_nodes`` makes.

    ``add_nodes`` returns the shader nodes whose ``Normal`` input takes the normal
    chain; every ``tex_*`` image node it adds gets the original textures' UVs.
    """
    original = p.original
    principled = p.sources.principled
    normal_src = _link_source(principled.inputs["Normal"])
    images = p.sources.image_nodes()
    vector_src = _link_source(images[0].inputs["Vector"]) if images else None
    keep = _upstream_nodes(principled.inputs["Normal"])
    if images:
        keep |= _upstream_nodes(images[0].inputs["Vector"])

    copy = original.copy()
    copy.richmat.original = original
    tree = copy.node_tree
    for node in [n for n in tree.nodes if n.name not in keep]:
        tree.nodes.remove(node)
    _frame_kept(tree)
    try:
        shaders = add_nodes(copy)
    except (RuntimeError, KeyError, ValueError, OSError):
        bpy.data.materials.remove(copy)
        raise
    if normal_src:
        for shader in shaders:
            tree.links.new(_output(tree, normal_src), shader.inputs["Normal"])
    if vector_src:
        for node in tree.nodes:
            if node.bl_idname == "ShaderNodeTexImage" and node.name.startswith("tex_"):
                tree.links.new(_output(tree, vector_src), node.inputs["Vector"])
    if not original.richmat.uid:
        original.richmat.uid = uuid.uuid4().hex
    return copy


def build_enhanced(p: SlotPlan, mat: EnhancedMaterial, textures: dict[str, Any], record: dict[str, Any],
                   cycles: cycles_builder.Graph) -> bpy.types.Material:
    """The original's copy with both enhanced graphs in place of its Principled BSDF, Cycles reading ``cycles``."""
    enhanced = copy_with_chains(p, lambda m: cycles_builder.add_enhanced_nodes(m, mat, textures, cycles=cycles))
    settings = enhanced.richmat
    settings.type, settings.seed = mat.type, mat.seed
    settings.amount, settings.auto_touch = mat.settings.get("amount", 1.0), mat.settings.get("auto_touch", False)
    settings.record = json.dumps(record, default=_jsonable)
    return enhanced


def _frame_kept(tree: bpy.types.NodeTree) -> None:
    """Put the kept original nodes in one labelled frame, left of the parameter textures."""
    kept = [n for n in tree.nodes if n.bl_idname != "NodeFrame"]
    if not kept:
        return
    frame = tree.nodes.new("NodeFrame")
    frame.name, frame.label = _KEEP_FRAME, "original normal map and UVs"
    right = max(n.location.x for n in kept)
    for node in kept:
        node.parent = None
        node.location = (node.location.x - right - 1000.0, node.location.y - 600.0)
        node.parent = frame


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(type(value).__name__)


def textured_maps(mat: EnhancedMaterial) -> dict[str, ParamMap]:
    maps = {"base_color": mat.base_color, **mat.params}
    return {k: m for k, m in maps.items() if not m.is_constant}


def install(p: SlotPlan, enhanced: bpy.types.Material) -> None:
    """Replace a previous enhanced copy (everywhere it is used) and put the new one in the slot."""
    original = p.original
    previous = original.richmat.enhanced
    if previous is not None and previous != enhanced:
        previous.user_remap(enhanced)
        remove_material(previous)
    enhanced.name = original.name + SUFFIX
    original.richmat.enhanced = enhanced
    p.obj.material_slots[p.slot_index].material = enhanced


def remove_material(material: bpy.types.Material) -> None:
    """A material with the preview images and the OSL text only it uses."""
    owned = [n.image for n in material.node_tree.nodes
             if n.bl_idname == "ShaderNodeTexImage" and n.name.startswith("tex_") and n.image]
    texts = [n.script for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeScript" and n.script]
    bpy.data.materials.remove(material)
    for image in owned:
        if image.users == 0:
            bpy.data.images.remove(image)
    for text in texts:
        if text.users == 0:
            bpy.data.texts.remove(text)


def cycles_choice(scene: bpy.types.Scene) -> cycles_builder.Graph:
    """The graph Cycles should read: the exact OSL one where the scene's Cycles runs it."""
    return "osl" if cycles_builder.osl_runs(scene) else "native"


def keep_cycles_renderable(scene: bpy.types.Scene) -> list[str]:
    """Point every enhanced material that Cycles reads as OSL at its native graph when Cycles cannot
    run OSL in ``scene`` (a GPU without OptiX, or OSL off): a Script node renders black there."""
    if cycles_choice(scene) == "osl":
        return []
    switched = [m for m in bpy.data.materials if is_enhanced(m) and cycles_builder.cycles_graph(m) == "osl"]
    for material in switched:
        cycles_builder.use_in_cycles(material, "native")
    return [m.name for m in switched]


def uplift(obj: bpy.types.Object, all_slots: bool, requested: str, seed: int, cycles: cycles_builder.Graph,
           max_size: int | None = PREVIEW_SIZE, amount: float = 1.0, touch: bool | None = None,
           words: dict[str, str] | None = None) -> list[str]:
    """Uplift the object's materials, Cycles reading ``cycles``; returns one line per material for the report.

    Every slot is checked and enhanced before the first datablock is created, so
    bad input anywhere changes nothing.
    """
    work = [(p, enhance_slot(p, requested, seed, max_size, amount, touch, words)) for p in plan(obj, all_slots)]
    lines = []
    for p, mat in work:
        textures = {name: preview_image(f"richmat {p.original.name} {name}", pmap)
                    for name, pmap in textured_maps(mat).items()}
        record = {"requested_type": requested, "settings": mat.settings, **({"words": words} if words else {})}
        try:
            enhanced = build_enhanced(p, mat, textures, record, cycles)
        except (RuntimeError, KeyError, ValueError):
            for image in textures.values():
                bpy.data.images.remove(image)
            raise
        install(p, enhanced)
        note = mat.settings.get("type_note") or ""
        touch = (f", amount {mat.settings['amount']:.2f}" if mat.settings.get("amount", 1.0) != 1.0 else "") + \
            (", lighter on dark texels" if mat.settings.get("auto_touch") else "")
        lines.append(f"{p.original.name}: type {mat.type}{touch}" + (f" ({note})" if note else ""))
    return lines
