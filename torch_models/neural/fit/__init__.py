"""Fitting a material's latents against the frozen decoder (paper sec. 4.3).

``material.fit_material`` is the fit the CLI, the add-on's backend and the farm run: it reads
the folder's texel vectors (``material_vectors``), past a budget chooses representatives of
them (``representatives``), fits their latents (``latents``), has the decoder's kind check
their energy (``neural.energy``), measures the fit error (``error``) and writes the neural folder.
"""
