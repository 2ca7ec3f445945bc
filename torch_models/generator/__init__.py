"""Text-to-neural-material generator (paper sec. 5.2): a small conditional multi-view diffusion model."""

# Sampling steps, views and samples averaged of a generation, chosen from bench/generate_speed.py
# (docs/reports/generate_speed.json; the samples from its samples sweep, docs/reports/generate_samples.json).
# Here, torch-free, so that the CLI's --help reads them without importing torch.
DEFAULT_STEPS = 18
DEFAULT_VIEWS = 12
DEFAULT_SAMPLES = 4
DEFAULT_GUIDANCE = 2.0  # classifier-free guidance scale, from bench/generate_guidance.py
DEFAULT_TEXTURE_SIZE = 64  # latent texture side when the input's base colour is constant or larger
