"""reconstruct.registration: rigid registration: a scan to a reference from any starting
frame, and many range scans to each other with no initial pose.

One stack: ``features`` (FPFH, matches, Kabsch, the seeded RANSAC) and ``icp`` (ICP and
``Registration``, the result every registration returns) under ``rigid`` (a scan to a
reference), ``pairwise`` (two scans, no initial pose) and ``multiway`` (all scans: pairs,
pose graph, fine alignment; the fine alignment alone from given poses); beside them
``oriented`` (oriented samples in a scan's canonical frame), ``verify`` (overlap,
agreement and lines of sight of a candidate) and ``joint`` (multi-view ICP).

Every name below is importable from the room (``from reconstruct.registration import
NAME``), loaded on first use.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "ALIGN_METHODS": "rigid",
    "LOW_FITNESS": "rigid",
    "Registration": "icp",
    "icp": "icp",
    "rigid_step": "icp",
    "score": "icp",
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
