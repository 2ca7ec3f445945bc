"""The neural material: the decoder and its candidates, the fit's accuracy, cost and budget, latent
robustness and where the neural material fails (docs/neural-material.md)."""
