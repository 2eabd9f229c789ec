"""acquire.sfm: structure-from-motion captures: camera paths (orbits, hemispheres, hand-held
walks), the capture, and the nerfstudio export.

Modules: ``capture``, ``nerfstudio``, ``paths``.

Every name below is importable from the room (``from acquire.sfm import NAME``), loaded on
first use.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "PATH_KINDS": "capture",
    "PathConfig": "capture",
    "SfmCaptureConfig": "capture",
    "GL_FROM_CV": "nerfstudio",
    "read_transforms": "nerfstudio",
    "transforms_dict": "nerfstudio",
    "write_transforms": "nerfstudio",
    "handheld_walk": "paths",
    "hemisphere": "paths",
    "interpolate_pose": "paths",
    "orbit_rings": "paths",
    "subframe_poses": "paths",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
