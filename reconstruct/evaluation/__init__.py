"""reconstruct.evaluation: measures against ground truth: F-score, accuracy and completeness
of a surface; disparity metrics (Middlebury); the similarity alignment and pose errors of
cameras; the errors of registered scan poses after a robust gauge fit; per-view camera errors
against reference cameras after a robust Sim(3) fit; a mesh drawn into views against a mask
per view (inside the silhouettes, silhouettes covered).

Modules: ``disparity``, ``evaluate``, ``sim3``, ``scan_poses``, ``camera_poses``, ``masks``.

Every name below is importable from the room (``from reconstruct.evaluation import NAME``),
loaded on first use.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "disparity_metrics": "disparity",
    "nonoccluded_mask": "disparity",
    "DEFAULT_MAX_SAMPLES": "evaluate",
    "EvaluateConfig": "evaluate",
    "EvaluationResult": "evaluate",
    "SAMPLES_PER_TAU2": "evaluate",
    "TAU_FRACTION": "evaluate",
    "default_tau": "evaluate",
    "fscore_at": "evaluate",
    "MaskScores": "masks",
    "mask_scores": "masks",
    "mesh_hits": "masks",
    "PoseErrors": "sim3",
    "Sim3": "sim3",
    "align_cameras": "sim3",
    "umeyama": "sim3",
    "ScanPoseErrors": "scan_poses",
    "CameraErrors": "camera_poses",
    "compare_cameras": "camera_poses",
    "read_estimated_cameras": "camera_poses",
    "robust_umeyama": "sim3",
    "joint_similarity": "sim3",
    "relative_rotation_errors": "camera_poses",
    "compare_scan_poses": "scan_poses",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
