"""Noise: exact improved Perlin noise and the family built on it."""

from procgen.noise.perlin import REFERENCE_PERMUTATION, noise3, perlin, perm_table

__all__ = ["perlin", "perm_table", "noise3", "REFERENCE_PERMUTATION"]
