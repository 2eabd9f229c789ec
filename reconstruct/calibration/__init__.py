"""reconstruct.calibration: calibration shared by every method: a camera from board views
(Zhang), a user's board photos, a stereo pair and a turntable axis, the rectification of a
pair, and the OpenCV YAML files.

Modules: ``camera``, ``images``, ``io``, ``rectify``, ``stereo``, ``turntable``.

Every name below is importable from the room (``from reconstruct.calibration import NAME``),
loaded on first use.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "CameraCalibration": "camera",
    "board_pose": "camera",
    "bootstrap_cameras": "camera",
    "calibrate_camera": "camera",
    "calibrate_camera_points": "camera",
    "detect_board": "camera",
    "to_gray": "camera",
    "calibrate_camera_images": "images",
    "calibrate_stereo_images": "images",
    "epipolar_errors": "images",
    "sorted_images": "images",
    "read_camera_yaml": "io",
    "read_stereo_yaml": "io",
    "write_camera_yaml": "io",
    "write_stereo_yaml": "io",
    "Rectification": "rectify",
    "StereoCalibration": "rectify",
    "rectify_pair": "rectify",
    "PairViews": "stereo",
    "calibrate_pair": "stereo",
    "calibrate_turntable_axis": "stereo",
    "calibrate_turntable_mount": "stereo",
    "detect_pair_views": "stereo",
    "world_from_cam_at": "stereo",
    "fit_axis": "turntable",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
