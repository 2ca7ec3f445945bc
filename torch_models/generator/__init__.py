"""Text-to-neural-material generator (paper sec. 5.2): a small conditional multi-view diffusion model."""

# Sampling steps, views and samples averaged of a generation, chosen from bench/generate_speed.py
# (docs/reports/generate_speed.json; the samples from its samples sweep, docs/reports/generate_samples.json).
# Here, torch-free, so that the CLI's --help reads them without importing torch.
DEFAULT_STEPS = 18
DEFAULT_VIEWS = 12
DEFAULT_SAMPLES = 4
DEFAULT_TEXTURE_SIZE = 64  # latent texture side when the input's base colour is constant or larger
# Classifier-free guidance scale per enhancement type: per type, the value of 1, 1.5, 2 and 2.5
# with the best mean PSNR on its held-out procedural objects (bench/generate_guidance.py,
# docs/reports/generate_guidance.json). Type 4's captions are met by the prompted model alone:
# more guidance overshoots them. Guidance 1 also skips the unconditional pass.
GUIDANCE_BY_TYPE: dict[int, float] = {0: 2.5, 1: 2.0, 2: 2.5, 3: 2.0, 4: 1.0, 5: 1.5}


def guidance_for(type_: int) -> float:
    """The guidance a generation of enhancement type ``type_`` samples with by default."""
    return GUIDANCE_BY_TYPE[type_]
