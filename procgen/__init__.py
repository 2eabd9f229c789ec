"""procgen: procedural modeling, and the bottom layer every other package stands on.

Modeling: :mod:`procgen.noise` (exact Perlin, fBm, turbulence, ridged, curl, solid
textures), :mod:`procgen.fractals` (midpoint displacement, diamond-square, IFS,
escape-time sets, box counting), :mod:`procgen.terrain`, :mod:`procgen.implicit`
(hypertexture, marching cubes), :mod:`procgen.lsystem` (grammars, derivation,
turtle, geometry), :mod:`procgen.sweeps`, :mod:`procgen.shells`,
:mod:`procgen.shape_grammar`, :mod:`procgen.city`. Shared
infrastructure, public to the other packages: :mod:`procgen.validate` (argument
checks), :mod:`procgen.files` (atomic outputs, TOML/JSON), :mod:`procgen.meshes`
(the canonical mesh type and its conversions), :mod:`procgen.mesh_io` (mesh,
point and image files).

procgen imports no other scanamp package.
"""

import os as _os

# numba's TBB layer is too old on Debian 12 and warns on first use; OpenMP is
# present (libgomp1 is a set-up requirement). A user's own choice still wins.
_os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
