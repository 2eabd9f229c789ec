"""acquire.laser: the sheet-of-light laser scanner on a turntable or stage: the rig
(turntable or linear stage) and its capture with calibration views. The laser sheet itself
is a light of the shared render room (:mod:`acquire.render.laser_sheet`).

Modules: ``capture``, ``rig``.

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
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
