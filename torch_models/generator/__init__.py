"""Text-to-neural-material generator (paper sec. 5.2): a small conditional multi-view diffusion model."""
