"""procgen: procedural modeling.

:mod:`procgen.noise` (exact Perlin, fBm, turbulence, ridged, curl, solid textures),
:mod:`procgen.fractals` (midpoint displacement, diamond-square, IFS, escape-time sets,
box counting), :mod:`procgen.terrain`, :mod:`procgen.implicit` (hypertexture, marching
cubes), :mod:`procgen.lsystem` (grammars, derivation, turtle, geometry),
:mod:`procgen.sweeps`, :mod:`procgen.shells`, :mod:`procgen.shape_grammar`,
:mod:`procgen.city`, :mod:`procgen.weber_penn` (Weber & Penn trees, species files, QSM and
the laws of real trees), and :mod:`procgen.amplify` (mesh amplification operators).

procgen imports only :mod:`core`.
"""

import core as _core  # noqa: F401  (sets numba's threading layer before any kernel compiles)
