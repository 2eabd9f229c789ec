"""reconstruct.evaluation: measures against ground truth: F-score, accuracy and completeness
of a surface; disparity metrics (Middlebury); the similarity alignment and pose errors of
cameras.

Modules: ``disparity``, ``evaluate``, ``sim3``.

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
    "PoseErrors": "sim3",
    "Sim3": "sim3",
    "align_cameras": "sim3",
    "umeyama": "sim3",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
