"""acquire.laser: the sheet-of-light laser scanner: the laser sheet (a light), the rig
(turntable or linear stage) and its capture with calibration views.

Modules: ``capture``, ``rig``, ``sheet``.

Every name below is importable from the room (``from acquire.laser import NAME``), loaded on
first use.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "board_pose_axis": "capture",
    "board_poses_camera": "capture",
    "board_poses_laser": "capture",
    "LaserCaptureConfig": "rig",
    "LaserRig": "rig",
    "LaserFrame": "sheet",
    "LaserRenderer": "sheet",
    "LaserSheet": "sheet",
    "camera_directions": "sheet",
    "plane_of": "sheet",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
