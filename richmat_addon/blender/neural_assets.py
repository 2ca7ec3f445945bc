"""Add-on preferences (the torch backend, found by itself when it can be) and the fitted latent
textures in a material."""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import bpy

from ..core.neural_folder import LATENT_FILES
from . import neural_backend
from .pbr_source import InputProblem

ADDON = __package__.rsplit(".", 1)[0]  # "bl_ext.<repo>.richmat" when installed as an extension
LATENT_NODES = ("neural_latent_0", "neural_latent_1")
_FRAME = "richmat_frame_neural"


class RichmatPreferences(bpy.types.AddonPreferences):
    bl_idname = ADDON

    python: bpy.props.StringProperty(
        name="Backend Python", subtype="FILE_PATH",
        description="A Python with torch and richmat's torch_models, used when Blender's own has no torch")
    source_dir: bpy.props.StringProperty(
        name="Richmat Source", subtype="DIR_PATH",
        description="The richmat checkout holding torch_models (not needed if it is pip-installed)")
    weights_dir: bpy.props.StringProperty(
        name="Decoder Weights", subtype="DIR_PATH",
        description="A trained decoder folder; empty: the weights shipped with torch_models")
    generator_dir: bpy.props.StringProperty(
        name="Generator Weights", subtype="DIR_PATH",
        description="A train-generator run folder for Generate Material; empty: the generator shipped "
                    "with torch_models")

    def draw(self, context: bpy.types.Context) -> None:
        try:
            found = backend(context)
            self.layout.label(text=f"Torch backend: {found.python}", icon="CHECKMARK")
        except neural_backend.BackendProblem as exc:
            self.layout.label(text=f"Fit writes the encoder's latents only; {exc}", icon="INFO")
        for name in ("python", "source_dir", "weights_dir", "generator_dir"):
            self.layout.prop(self, name)


def preferences(context: bpy.types.Context):
    """The add-on's preferences, or their defaults when it was registered without the add-on system."""
    addon = context.preferences.addons.get(ADDON)
    if addon is not None and addon.preferences is not None:
        return addon.preferences
    return SimpleNamespace(python="", source_dir="", weights_dir="", generator_dir="")


def search_from() -> list[Path]:
    """Where a backend's .venv is looked for: the add-on's folder and the current .blend's, and above."""
    return [neural_backend.ADDON_ROOT] + ([Path(bpy.data.filepath).parent] if bpy.data.filepath else [])


def backend(context: bpy.types.Context) -> neural_backend.Backend:
    """The torch backend to run, or a BackendProblem naming what to install and where."""
    prefs = preferences(context)
    return neural_backend.find_backend(bpy.path.abspath(prefs.python), bpy.path.abspath(prefs.source_dir),
                                       search_from())


def backend_in_sight(context: bpy.types.Context) -> bool:
    """Whether a backend may be there, without starting a Python (for polls, asked on every redraw)."""
    return (neural_backend.blender_has_torch() or bool(preferences(context).python)
            or bool(neural_backend.venv_candidates(search_from())))


def decoder_folder(context: bpy.types.Context) -> Path:
    """The decoder folder (weights.safetensors, state.json) the latents belong to, or an InputProblem."""
    prefs = preferences(context)
    folder = neural_backend.decoder_dir(bpy.path.abspath(prefs.weights_dir), bpy.path.abspath(prefs.source_dir))
    if folder is None:
        raise InputProblem("no decoder weights: set Decoder Weights (or Richmat Source) in "
                           "Preferences > Add-ons > Richmat")
    return folder


def assign_latents(enhanced: bpy.types.Material, folder: Path) -> str:
    """Load the two latent textures into image nodes of the enhanced material (replacing old ones)."""
    files = [folder / name for name in LATENT_FILES]
    if not all(f.is_file() for f in files):
        return "constant material: one latent vector in neural.json, no textures"
    tree = enhanced.node_tree
    frame = tree.nodes.get(_FRAME) or tree.nodes.new("NodeFrame")
    frame.name, frame.label = _FRAME, "neural latents"
    for k, (node_name, file) in enumerate(zip(LATENT_NODES, files)):
        node = tree.nodes.get(node_name) or tree.nodes.new("ShaderNodeTexImage")
        node.name = node.label = node_name
        image = bpy.data.images.load(str(file), check_existing=True)
        image.reload()
        image.colorspace_settings.name = "Non-Color"
        node.image = image
        node.parent = frame
        node.location_absolute = (-600.0, 600.0 + 280.0 * k)
    return "latent textures assigned"
