"""reconstruct.laser: the laser scanner's reconstruction: stripe peak detection, laser-plane
and axis calibration, the error model, the pipeline and its evaluation.

Modules: ``calibration``, ``error_model``, ``evaluation``, ``pipeline``, ``stripe``.

Every name below is importable from the room (``from reconstruct.laser import NAME``),
loaded on first use.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "AxisCalibration": "calibration",
    "LaserPlaneCalibration": "calibration",
    "calibrate_laser_plane": "calibration",
    "calibrate_stage": "calibration",
    "calibrate_turntable_axis": "calibration",
    "fit_plane": "calibration",
    "intersect_rays_plane": "calibration",
    "pixel_rays": "calibration",
    "refit_laser_plane": "calibration",
    "PeakErrorAccumulator": "error_model",
    "closed_form_sigma_z": "error_model",
    "depth_sigma": "error_model",
    "estimate_peak_sigma": "error_model",
    "log_albedo_gradient": "error_model",
    "peak_sigma_model": "error_model",
    "pixel_variance": "error_model",
    "evaluate_laser": "evaluation",
    "visible_lit_mask": "evaluation",
    "DEFAULT_DETECTOR": "pipeline",
    "LaserReconConfig": "pipeline",
    "STAGES": "pipeline",
    "extract_frames": "pipeline",
    "run": "pipeline",
    "DETECTORS": "stripe",
    "StripeOptions": "stripe",
    "argmax_peaks": "stripe",
    "detect_peaks": "stripe",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
