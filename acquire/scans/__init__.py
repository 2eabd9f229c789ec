"""acquire.scans: multi-view range scanning: a sheet-of-light scanner head on a
linear sweep, with its factory geometry and on-board peak detection, placed at many
viewpoints around and above a scene; each sweep is written as a PLY range grid in the
scanner's own frame, the true placements for evaluation only.

Modules: ``head`` (:class:`ScanHead`, :class:`SpacetimePeaks`, :func:`stripe_peaks`),
``capture`` (:class:`ScansCaptureConfig`, :func:`view_poses`, :func:`scan_view`,
:func:`grid_layout`, :func:`capture_scans`).

Every name below is importable from the room (``from acquire.scans import NAME``), loaded on
first use.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "ScanHead": "head",
    "stripe_peaks": "head",
    "SpacetimePeaks": "head",
    "grid_layout": "capture",
    "ScansCaptureConfig": "capture",
    "view_poses": "capture",
    "scan_view": "capture",
    "capture_scans": "capture",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
