"""Noise: exact improved Perlin noise and the family built on it.

:func:`perlin` (exact improved noise); :mod:`procgen.noise.fractal` (fBm, turbulence,
ridged multifractal, marble, tileable noise, domain warping, curl noise, bias and
gain); :mod:`procgen.noise.solid` (solid textures for the renderer, by name in
:data:`SOLID_TEXTURES`).
"""

from procgen.noise._kernels import curl_potentials, noise3_grad
from procgen.noise.fractal import bias, curl, fbm, gain, marble, ridged, tileable, turbulence, warp
from procgen.noise.perlin import REFERENCE_PERMUTATION, noise3, perlin, perm_table
from procgen.noise.solid import SOLID_TEXTURES, color_ramp, fire_ramp

__all__ = [
    "perlin", "perm_table", "noise3", "noise3_grad", "curl_potentials", "REFERENCE_PERMUTATION",
    "fbm", "turbulence", "ridged", "marble", "tileable", "warp", "curl", "bias", "gain",
    "SOLID_TEXTURES", "color_ramp", "fire_ramp",
]
