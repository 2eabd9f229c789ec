"""core: the base every other scanamp package stands on; it imports none of them.

- :mod:`core.validate`  argument checks (one helper per kind of check) and ``InputError``
- :mod:`core.files`     atomic outputs, JSON/TOML reading and writing
- :mod:`core.config`    configuration dataclasses: declared options, TOML in and out
- :mod:`core.meshes`    the canonical mesh (``open3d.geometry.TriangleMesh``), its
  conversions to pymeshlab and pyvista, and mesh measures
- :mod:`core.io`        the file formats: meshes, images, range grids, E57, LAS, rasters,
  tree tables, other tools' cameras
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
# COLMAP logs through glog, which by default writes a log file per severity into the
# temporary directory at the first message (``.HOST.USER.log.INFO.DATE.PID``): a user's
# /tmp fills with them. To stderr instead (quieted by pycolmap.logging.minloglevel, as the
# SfM stages do). Read when pycolmap's library loads, so it is set here, before that.
_os.environ.setdefault("GLOG_logtostderr", "1")


def _keep_freed_blocks() -> None:
    """Let glibc's malloc keep large freed blocks for the next allocation.

    By default an array above 32 MB is mapped fresh from the system and unmapped when
    freed, and more than 64 MB free at the top of the heap is given back: every frame
    of the renderer would page-fault its temporaries in again, zeroed by the kernel.
    Here blocks up to 256 MB come from the heap and up to 512 MB of free heap is kept
    (bench_render measures the effect), so the process's memory stays near its peak
    instead of shrinking between frames. Set only when the
    environment sets no malloc tunables (Dask's nanny sets ``MALLOC_TRIM_THRESHOLD_``
    for its workers, which then keep its policy), and only with glibc.
    """
    if any(k in _os.environ for k in ("GLIBC_TUNABLES", "MALLOC_MMAP_THRESHOLD_",
                                      "MALLOC_TRIM_THRESHOLD_")):
        return
    try:
        import ctypes

        mallopt = ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):   # not glibc
        return
    m_trim_threshold, m_mmap_threshold = -1, -3
    mallopt(m_mmap_threshold, 256 << 20)
    mallopt(m_trim_threshold, 512 << 20)


_keep_freed_blocks()
