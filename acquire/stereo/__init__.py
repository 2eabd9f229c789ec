"""acquire.stereo: passive and active stereo and structured light: the rig (two cameras and
a projector), the projector's patterns, and both captures.

Modules: ``capture``, ``capture_sl``, ``patterns``, ``rig``.

Every name below is importable from the room (``from acquire.stereo import NAME``), loaded
on first use.

Names defined by more than one module are reached through their module: ``capture``.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "pattern_sequence": "capture_sl",
    "gray_code_bits": "patterns",
    "gray_code_patterns": "patterns",
    "phase_shift_patterns": "patterns",
    "random_dots": "patterns",
    "white_black": "patterns",
    "CalibrationOptions": "rig",
    "CameraOptions": "rig",
    "GeometryOptions": "rig",
    "LensOptions": "rig",
    "ProjectorOptions": "rig",
    "RenderOptions": "rig",
    "RigConfig": "rig",
    "SLCaptureConfig": "rig",
    "StereoCaptureConfig": "rig",
    "rot_y": "rig",
    "rot_z": "rig",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
