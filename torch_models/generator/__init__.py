"""Text-to-neural-material generator (paper sec. 5.2): a small conditional multi-view diffusion model."""
from richmat_addon.core import enhancement_types

# Sampling steps, views and samples averaged of a generation, chosen from bench/generator/generate_speed.py
# (docs/reports/generate_speed.json; the samples from its samples sweep, in docs/history.md).
# Here, torch-free, so that the CLI's --help reads them without importing torch.
DEFAULT_STEPS = 18
DEFAULT_VIEWS = 12
DEFAULT_SAMPLES = 4
DEFAULT_TEXTURE_SIZE = 64  # latent texture side when the input's base colour is constant or larger


def guidance_for(type_: int) -> float:
    """The guidance a generation of enhancement type ``type_`` samples with by default (the type table's)."""
    return enhancement_types.TYPES[type_].guidance


def guidance_by_type() -> dict[int, float]:
    """Every type's default guidance, as the CLI's help and the benches' reports list it."""
    return {t.index: t.guidance for t in enhancement_types.TYPES}
