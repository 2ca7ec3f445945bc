"""Torch evaluators of the enhanced BRDF: lobes, lookup tables and the layered model."""
