"""reconstruct.surface: from points and depth maps to a clean surface: TSDF fusion, screened
Poisson, mesh cleaning, and which way is up and which part is the ground.

Modules: ``clean``, ``ground``, ``meshing``, ``tsdf``, ``up``.

Every name below is importable from the room (``from reconstruct.surface import NAME``),
loaded on first use.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "CleanOptions": "clean",
    "clean_mesh": "clean",
    "component_areas": "clean",
    "ground_mask": "ground",
    "MeshingOptions": "meshing",
    "estimate_normals": "meshing",
    "points_to_mesh": "meshing",
    "poisson_mesh": "meshing",
    "remove_outliers": "meshing",
    "TSDFVolume": "tsdf",
    "fuse_depth_maps": "tsdf",
    "undistort_depth": "tsdf",
    "UpEstimate": "up",
    "estimate_up": "up",
    "find_camera_model": "up",
    "up_from_cameras": "up",
    "up_from_mesh": "up",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
