"""The dataset farm: render speed and denoising, the intrinsics pass's samples, an asset's cost stage by
stage, and a batch killed and restarted, locally and on SLURM (docs/batch.md)."""
