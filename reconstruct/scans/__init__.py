"""reconstruct.scans: range scans from free viewpoints: the scan as registration
and merging see it (points, normals, lines of sight, confidences, the range image's
triangles and grid) and loading scans from range images, clouds, meshes, E57 files,
folders and ``.conf`` files.

Modules: ``scan`` (:class:`RangeScan`, triangulating a range image, scans of clouds),
``load`` (:func:`load_scans`, :func:`check_scans`).

Every name below is importable from the room (``from reconstruct.scans import NAME``),
loaded on first use.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "RangeScan": "scan",
    "scan_from_grid": "scan",
    "scan_from_points": "scan",
    "grid_sight": "scan",
    "load_scans": "load",
    "check_scans": "load",
    "scan_files": "load",
    "SCAN_SUFFIXES": "load",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
