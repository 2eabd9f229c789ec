"""core: the base every other scanamp package stands on; it imports none of them.

- :mod:`core.validate`  argument checks (one helper per kind of check) and ``InputError``
- :mod:`core.files`     atomic outputs, JSON/TOML reading and writing
- :mod:`core.config`    configuration dataclasses: declared options, TOML in and out
- :mod:`core.meshes`    the canonical mesh (``open3d.geometry.TriangleMesh``), its
  conversions to pymeshlab and pyvista, and mesh measures
- :mod:`core.mesh_io`   mesh, point-cloud and polyline files
- :mod:`core.image_io`  image files
- :mod:`core.frames`    rotations and rigid transforms
- :mod:`core.sampling`  area-uniform surface samples, voxel thinning
- :mod:`core.progress`  progress of long work (the CLI decides whether it shows)
"""

import os as _os

# numba's TBB layer is too old on Debian 12 and warns on first use; OpenMP is
# present (libgomp1 is a set-up requirement). A user's own choice still wins.
_os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
# OpenMP's workers spin after each parallel loop by default; the renderer alternates
# numba loops with Embree's casts (its own thread pool) on the same cores, and the
# spinning took the cores from Embree: a shaded frame took 4.3x the bare cast with
# spinning, 3.0x without (bench_render). Set before libgomp loads (it reads it once).
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
