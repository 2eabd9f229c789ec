"""reconstruct.registration: rigid registration: a scan to a reference from any starting
frame, and many range scans to each other with no initial pose.

Modules: ``rigid`` (a scan to a reference), ``oriented`` (oriented samples in a scan's
canonical frame), ``features`` (FPFH, seeded RANSAC), ``verify`` (overlap, agreement and
lines of sight of a candidate), ``pairwise`` (two scans, no initial pose), ``joint``
(multi-view ICP), ``multiway`` (all scans: pairs, pose graph, fine alignment; the fine
alignment alone from given poses).

Every name below is importable from the room (``from reconstruct.registration import
NAME``), loaded on first use.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "ALIGN_METHODS": "rigid",
    "LOW_FITNESS": "rigid",
    "Registration": "rigid",
    "register": "rigid",
    "Oriented": "oriented",
    "canonical_frame": "oriented",
    "thin_oriented": "oriented",
    "fpfh": "features",
    "match_features": "features",
    "ransac_rigid": "features",
    "kabsch": "features",
    "Verdict": "verify",
    "VerifyOptions": "verify",
    "ViewMap": "verify",
    "verify_pair": "verify",
    "Prepared": "pairwise",
    "PairMatch": "pairwise",
    "prepare": "pairwise",
    "match_pair": "pairwise",
    "icp_point_to_plane": "pairwise",
    "JointAlignment": "joint",
    "MultiwayOptions": "multiway",
    "MultiwayResult": "multiway",
    "ScanPlacement": "multiway",
    "register_scans": "multiway",
    "refine_scans": "multiway",
    "auto_voxel": "multiway",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
