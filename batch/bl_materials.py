"""Blender side, materials: read each Principled BSDF as PBR inputs, unwrap meshes without UVs.

Both use the add-on's own code (``richmat_addon.blender.pbr_source`` read
leniently, ``richmat_addon.blender.unwrap``), so the farm and the add-on see a
material the same way. Any input the reader cannot follow keeps the socket's own
value, with a note; textures larger than ``max_texture`` are downscaled (noted);
missing image files fall back to the socket value (noted), as do textures of
meshes that cannot be unwrapped; a transparent material is rendered opaque (noted).

Two glTF layouts the add-on's reader leaves alone are handled here: vertex
colours multiplying the base colour (the glTF importer links COLOR_0 to it) are
baked into the base colour map, and a material whose textures read a second UV
set makes that set its meshes' render UV map, which the enhanced maps are
sampled with.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import bpy
import numpy as np

from richmat_addon.blender import mesh_maps
from richmat_addon.blender.pbr_source import InputProblem, find_principled, load_pbr, read_sources
from richmat_addon.blender.unwrap import unwrap
from richmat_addon.core.maps import ParamMap, PbrInputs

from .bl_scene import mesh_objects

MAX_UNWRAP_FACES = 200_000  # xatlas time grows fast; bigger meshes are recorded instead
DEFAULT_MATERIAL = "richmat_default"
UNTEXTURED_SIZE = 256  # map size for a material without textures (dust masks, baked vertex colours)


@dataclass
class MaterialSource:
    material: bpy.types.Material
    pbr: PbrInputs
    notes: list[str] = field(default_factory=list)
    uv_map: str | None = None  # the UV map its textures read; None: the render UV map
    vertex_colours: str | None = None  # the colour attribute multiplying its base colour ("": the render one)


def ensure_materials() -> None:
    """Meshes without a material get one plain grey Principled material."""
    bare = [o for o in mesh_objects() if not any(s.material for s in o.material_slots)]
    if bare:
        mat = bpy.data.materials.new(DEFAULT_MATERIAL)
        for obj in bare:
            obj.data.materials.clear()
            obj.data.materials.append(mat)


def used_materials() -> list[bpy.types.Material]:
    seen: dict[str, bpy.types.Material] = {}
    for obj in mesh_objects():
        for slot in obj.material_slots:
            if slot.material is not None:
                seen.setdefault(slot.material.name, slot.material)
    return list(seen.values())


def map_size(pbr: PbrInputs, max_texture: int) -> tuple[int, int]:
    """(H, W) of the material's largest texture, or of the untextured maps (capped by ``max_texture``)."""
    sizes = [m.shape for m in (pbr.base_color, pbr.roughness, pbr.metalness) if m.shape]
    return max(sizes, key=lambda s: s[0] * s[1]) if sizes else (min(UNTEXTURED_SIZE, max_texture),) * 2


def _take_vertex_colours(mat: bpy.types.Material) -> str | None:
    """Unlink a colour attribute from Base Color, leaving what it multiplied there; its name, or None.

    The glTF importer's layouts: Color Attribute -> Base Color, and Mix Multiply of it
    and a texture or a colour -> Base Color.
    """
    try:
        socket = find_principled(mat).inputs["Base Color"]
    except InputProblem:
        return None
    if not socket.is_linked:
        return None
    tree, node = mat.node_tree, socket.links[0].from_node
    if node.bl_idname == "ShaderNodeVertexColor":
        tree.links.remove(socket.links[0])
        socket.default_value = (1.0, 1.0, 1.0, 1.0)
        return node.layer_name
    if not (node.bl_idname == "ShaderNodeMix" and node.data_type == "RGBA" and node.blend_type == "MULTIPLY"
            and not node.inputs["Factor"].is_linked and node.inputs["Factor"].default_value == 1.0):
        return None
    a, b = (next(s for s in node.inputs if s.identifier == i) for i in ("A_Color", "B_Color"))
    for colours, other in ((a, b), (b, a)):
        if colours.is_linked and colours.links[0].from_node.bl_idname == "ShaderNodeVertexColor":
            layer = colours.links[0].from_node.layer_name
            if other.is_linked:
                tree.links.new(other.links[0].from_socket, socket)
            else:
                tree.links.remove(socket.links[0])
                socket.default_value = other.default_value
            return layer
    return None


def _uv_map(node: bpy.types.ShaderNodeTexImage) -> str | None:
    """The UV map an image node reads: a UV Map node up its Vector input (through Mapping nodes), else None."""
    socket = node.inputs["Vector"]
    while socket.is_linked:
        up = socket.links[0].from_node
        if up.bl_idname == "ShaderNodeUVMap":
            return up.uv_map or None
        if up.bl_idname not in ("ShaderNodeMapping", "NodeReroute"):
            return None
        socket = up.inputs[0]
    return None


def _transparency_note(mat: bpy.types.Material) -> str | None:
    """A transparent source material (glTF alphaMode BLEND or MASK) is rendered opaque: the note saying so."""
    try:
        alpha = find_principled(mat).inputs["Alpha"]
    except InputProblem:
        return None
    if not alpha.is_linked and alpha.default_value >= 1.0:
        return None
    kind = "alpha blending" if mat.surface_render_method == "BLENDED" else "transparency"
    source = "its Alpha input is linked" if alpha.is_linked else f"alpha {alpha.default_value:.3g}"
    return f"{mat.name!r} has {kind} ({source}): rendered opaque, the enhanced material has no alpha"


def read_pbr(mat: bpy.types.Material, max_texture: int) -> MaterialSource:
    """The add-on's reader, lenient: what it cannot follow keeps the socket's value, with a note.

    Vertex colours on the base colour are taken out first (``bake_vertex_colours``
    puts them back as texels), and the UV map the textures read is recorded.
    """
    vertex_colours = _take_vertex_colours(mat)
    sources = read_sources(mat, "lenient")
    pbr = load_pbr(sources, max_texture)
    transparency = _transparency_note(mat)
    if transparency is not None:
        sources.notes.append(transparency)
    uv_maps = list(dict.fromkeys(_uv_map(node) for node in sources.image_nodes()))
    if len(uv_maps) > 1:
        sources.notes.append(f"the textures of {mat.name!r} read {len(uv_maps)} UV maps "
                             f"({', '.join(m or 'the render UV map' for m in uv_maps)}): the enhanced maps "
                             f"use the first")
    return MaterialSource(mat, pbr, sources.notes, uv_maps[0] if uv_maps else None, vertex_colours)


def render_uv_maps(sources: list[MaterialSource]) -> list[str]:
    """Make the UV map each material's textures read the render UV map of its meshes; notes.

    The enhanced maps are sampled with the render UV map, and world maps and baked
    vertex colours are rasterised in it. Each mesh with several UV sets gets a note
    saying which one its material's maps use.
    """
    notes: list[str] = []
    chosen: dict[str, tuple[str, str]] = {}  # mesh -> (render UV map, the material that chose it)
    for source in sources:
        name = source.material.name
        for obj, _ in material_surfaces(source.material):
            layers = obj.data.uv_layers
            if len(layers) < 2:
                continue
            render = next(uv.name for uv in layers if uv.active_render)
            wanted = source.uv_map if source.uv_map in layers else render
            earlier = chosen.setdefault(obj.data.name, (wanted, name))
            if earlier[0] != wanted:
                notes.append(f"{obj.name!r}: the maps of {name!r} read UV set {wanted!r}, but {earlier[1]!r} "
                             f"on the same mesh made {earlier[0]!r} the render UV map: {name!r} uses it too")
                continue
            layers[wanted].active_render = True
            notes.append(f"{obj.name!r} has {len(layers)} UV sets ({', '.join(uv.name for uv in layers)}): "
                         f"the maps of {name!r} use {wanted!r}")
    return notes


def bake_vertex_colours(source: MaterialSource, max_texture: int) -> None:
    """Multiply the base colour by the material's vertex colours, rasterised into its texture space; noted."""
    if source.vertex_colours is None:
        return
    label = repr(source.vertex_colours) if source.vertex_colours else "(the render colour attribute)"
    base = source.pbr.base_color
    size = base.shape or map_size(source.pbr, max_texture)
    colours, reason = mesh_maps.colour_map(material_surfaces(source.material), size, source.vertex_colours)
    if colours is None:
        source.notes.append(f"vertex colours {label} of {source.material.name!r} not baked ({reason}): "
                            "its base colour leaves them out")
        return
    source.pbr.base_color = ParamMap(np.clip(colours * base.value, 0.0, 1.0))
    source.notes.append(f"vertex colours {label} of {source.material.name!r} baked into its base colour "
                        f"({size[1]}x{size[0]} texels)")


def unwrap_missing_uvs() -> list[str]:
    """Give every mesh without UVs a UV atlas (xatlas, else Smart UV Project); say how, or why not."""
    notes = []
    for obj in mesh_objects():
        mesh = obj.data
        if mesh.uv_layers:
            continue
        if len(mesh.polygons) > MAX_UNWRAP_FACES:
            notes.append(f"{obj.name}: no UVs and {len(mesh.polygons)} faces (> {MAX_UNWRAP_FACES}): "
                         "not unwrapped, its materials stay untextured")
            continue
        try:
            done = unwrap(obj, triangulate=True)
        except InputProblem as problem:
            notes.append(f"{obj.name}: no UVs, not unwrapped: {problem}")
            continue
        notes.append(f"{obj.name}: no UVs, unwrapped with {done.method}")
    return notes


def material_surfaces(mat: bpy.types.Material) -> list[tuple[bpy.types.Object, list[int]]]:
    """Every mesh object using ``mat`` and its slots holding it: together they fill its texture space."""
    surfaces = [(o, [i for i, s in enumerate(o.material_slots) if s.material == mat]) for o in mesh_objects()]
    return [(o, slots) for o, slots in surfaces if slots]
