"""Stereo and structured-light rigs on a turntable: configuration and geometry.

A rig looks at the turntable axis (world Z through the origin) from ``distance``
metres at ``elevation_deg``. The stereo rig has two cameras ``baseline`` apart,
each turned toward the centre by half the ``vergence_deg`` (toe-in), each with its
own intrinsics and distortion, and optionally a random-dot projector between them.
The structured-light rig replaces the right camera by a projector (an inverse
camera) ``baseline`` to the right. The object sits on the turntable, which turns
to each of ``stage_angles_deg`` (a real turntable reports its angle; the rig's
pose relative to the axis is calibrated from board views, never taken from here).

Configs are TOML (every key optional; defaults below; nested tables of
:class:`RigConfig`); errors name file and field::

    [camera]                       # shared nominal settings
    width = 640
    height = 480
    fov_deg = 50.0
    [left]                         # per-camera differences
    dist = [0.02, -0.01, 0.0, 0.0, 0.0]
    focal_scale = 1.0
    principal_offset = [0.0, 0.0]  # pixels
    [right]
    dist = [-0.015, 0.005, 0.0, 0.0, 0.0]
    focal_scale = 1.01
    principal_offset = [2.0, -1.5]
    [rig]
    baseline = 0.08                # metres
    vergence_deg = 8.0
    distance = 0.45                # rig centre to the aim point
    elevation_deg = 25.0
    aim_height = 0.06
    stage_angles_deg = [0, 90, 180, 270]
    working_range = [0.3, 0.65]    # metres of depth the matcher searches
    [projector]
    enabled = true                 # stereo: random dots; structured light: always on
    width = 640
    height = 480
    fov_deg = 50.0
    intensity = 0.12
    density = 0.35
    dot_sigma_px = 0.7
    period_px = 16.0               # structured light: phase-shift period
    n_steps = 4
    [calibration]
    views = 10                     # board poses seen by the rig
    axis_views = 5                 # board poses on the turntable (axis calibration)
    squares_x = 7
    squares_y = 5
    square_length = 0.03
    marker_length = 0.022
    dictionary = "DICT_4X4_50"
    [render]
    supersample = 2
    ambient = 0.15
    [sensor]                       # acquire.sensor.Sensor fields
    read_noise = 2.0
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acquire.camera import Camera, look_at_cam_from_world
from acquire.sensor import Sensor
from acquire.targets import ChArUcoTarget
from core.config import Config, option

__all__ = ["RigConfig", "StereoCaptureConfig", "SLCaptureConfig", "CameraOptions",
           "LensOptions", "GeometryOptions", "ProjectorOptions", "CalibrationOptions",
           "RenderOptions", "rot_z", "rot_y"]


def rot_z(angle: float) -> np.ndarray:
    """(4, 4) rotation by ``angle`` radians about +Z."""
    c, s = np.cos(angle), np.sin(angle)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    return T


def rot_y(angle: float) -> np.ndarray:
    """(4, 4) rotation by ``angle`` radians about +Y."""
    c, s = np.cos(angle), np.sin(angle)
    T = np.eye(4)
    T[0, 0], T[0, 2], T[2, 0], T[2, 2] = c, s, -s, c
    return T


def _trans(x, y, z) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = [x, y, z]
    return T


@dataclass
class CameraOptions(Config):
    """``[camera]``: the nominal settings both cameras share."""

    width: int = option(640, unit="px", range="[16, 16384]", help="image width")
    height: int = option(480, unit="px", range="[16, 16384]", help="image height")
    fov_deg: float = option(50.0, unit="deg", range="(0, 170]", help="horizontal field of view")


@dataclass
class LensOptions(Config):
    """``[left]``/``[right]``: how one camera differs from the nominal."""

    dist: tuple[float, float, float, float, float] = option(
        (0.0, 0.0, 0.0, 0.0, 0.0), help="distortion k1, k2, p1, p2, k3 (OpenCV model)")
    focal_scale: float = option(1.0, range="(0, inf)", help="focal length over the nominal")
    principal_offset: tuple[float, float] = option((0.0, 0.0), unit="px",
                                                   help="principal point off the centre")


@dataclass
class GeometryOptions(Config):
    """``[rig]``: where the rig stands and what it searches."""

    baseline: float = option(0.08, unit="m", range="(0, inf)", help="camera centres apart")
    vergence_deg: float = option(8.0, unit="deg", range="[0, 90)",
                                 help="toe-in of the two cameras together")
    distance: float = option(0.45, unit="m", range="(0, inf)",
                             help="rig centre to the aim point")
    elevation_deg: float = option(25.0, unit="deg", range="[-89, 89]",
                                  help="rig raised above the aim point")
    aim_height: float = option(0.06, unit="m", range="(-inf, inf)",
                               help="aim point up the turntable axis")
    stage_angles_deg: tuple[float, ...] = option((0.0, 90.0, 180.0, 270.0), unit="deg",
                                                 help="turntable angles scanned")
    working_range: tuple[float, float] = option((0.3, 0.65), unit="m", range="(0, inf)",
                                                help="near and far depth the matcher searches")

    def __post_init__(self):
        super().__post_init__()
        if len(self.stage_angles_deg) == 0:
            raise ValueError("stage_angles_deg: expected at least one angle")
        if not self.working_range[0] < self.working_range[1]:
            raise ValueError(f"working_range: expected near < far, got {self.working_range}")


@dataclass
class ProjectorOptions(Config):
    """``[projector]``: stereo's random dots, structured light's pattern projector."""

    enabled: bool = option(True, help="stereo: project random dots (structured light: always)")
    width: int = option(640, unit="px", range="[16, 16384]", help="projector width")
    height: int = option(480, unit="px", range="[16, 16384]", help="projector height")
    fov_deg: float = option(50.0, unit="deg", range="(0, 170]", help="projector field of view")
    intensity: float = option(0.12, range="[0, inf)", help="projected irradiance")
    density: float = option(0.35, range="[0, 1]", help="fraction of projector pixels lit")
    dot_sigma_px: float = option(0.7, unit="px", range="(0, inf)", help="dot blur")
    period_px: float = option(16.0, unit="px", range="(0, inf)",
                              help="structured light: phase-shift period")
    n_steps: int = option(4, range="[3, 64]", help="structured light: phase steps")


@dataclass
class CalibrationOptions(Config):
    """``[calibration]``: the board and how many poses it is shown in."""

    views: int = option(10, range="[3, 1000]", help="board poses seen by the rig")
    axis_views: int = option(5, range="[3, 1000]",
                             help="board poses on the turntable (axis calibration)")
    squares_x: int = option(7, range="[3, 100]", help="ChArUco squares across")
    squares_y: int = option(5, range="[3, 100]", help="ChArUco squares down")
    square_length: float = option(0.03, unit="m", range="(0, inf)", help="square side")
    marker_length: float = option(0.022, unit="m", range="(0, inf)", help="marker side")
    dictionary: str = option("DICT_4X4_50", help="ArUco dictionary name")

    def target(self) -> ChArUcoTarget:
        return ChArUcoTarget(squares_x=self.squares_x, squares_y=self.squares_y,
                             square_length=self.square_length,
                             marker_length=self.marker_length, dictionary=self.dictionary)


@dataclass
class RenderOptions(Config):
    """``[render]``."""

    supersample: int = option(2, range="[1, 8]", help="rays per pixel side")
    ambient: float = option(0.15, range="[0, inf)", help="ambient light level")
    bounces: int = option(0, range="[0, 1]",
                          help="indirect bounces: 1 renders inter-reflections (slower)")


@dataclass
class RigConfig(Config):
    """A stereo or structured-light rig: every table of its TOML (module docstring)."""

    camera: CameraOptions = option(default_factory=CameraOptions, help="both cameras")
    left: LensOptions = option(default_factory=lambda: LensOptions(
        dist=(0.02, -0.01, 0.0, 0.0, 0.0)), help="the left camera")
    right: LensOptions = option(default_factory=lambda: LensOptions(
        dist=(-0.015, 0.005, 0.0, 0.0, 0.0), focal_scale=1.01,
        principal_offset=(2.0, -1.5)), help="the right camera")
    rig: GeometryOptions = option(default_factory=GeometryOptions, help="rig geometry")
    projector: ProjectorOptions = option(default_factory=ProjectorOptions, help="projector")
    calibration: CalibrationOptions = option(default_factory=CalibrationOptions,
                                             help="calibration board and poses")
    render: RenderOptions = option(default_factory=RenderOptions, help="rendering")
    sensor: Sensor = option(default_factory=Sensor, help="the cameras' sensor")

    def __post_init__(self):
        super().__post_init__()
        self.calibration.target()  # board checks

    # -- geometry (true values: used to render, stored as ground truth) ----------------
    def world_from_rig(self) -> np.ndarray:
        g = self.rig
        el = np.radians(g.elevation_deg)
        aim = np.array([0.0, 0.0, g.aim_height])
        eye = aim + g.distance * np.array([0.0, -np.cos(el), np.sin(el)])
        return np.linalg.inv(look_at_cam_from_world(eye, aim))

    def _camera(self, lens: LensOptions, world_from_cam: np.ndarray) -> Camera:
        c = self.camera
        f = 0.5 * c.width / np.tan(np.radians(c.fov_deg) / 2) * lens.focal_scale
        off = lens.principal_offset
        return Camera(c.width, c.height, f, f, (c.width - 1) / 2 + off[0],
                      (c.height - 1) / 2 + off[1], np.asarray(lens.dist, float),
                      np.linalg.inv(world_from_cam))

    def _projector(self, world_from_projector: np.ndarray) -> Camera:
        p = self.projector
        f = 0.5 * p.width / np.tan(np.radians(p.fov_deg) / 2)
        return Camera(p.width, p.height, f, f, (p.width - 1) / 2, (p.height - 1) / 2,
                      np.zeros(5), np.linalg.inv(world_from_projector))

    def stereo_cameras(self) -> tuple[Camera, Camera]:
        """True left and right cameras (world frame, turntable at angle 0)."""
        Wr = self.world_from_rig()
        v, b = np.radians(self.rig.vergence_deg) / 2, self.rig.baseline
        left = self._camera(self.left, Wr @ _trans(-b / 2, 0, 0) @ rot_y(v))
        right = self._camera(self.right, Wr @ _trans(b / 2, 0, 0) @ rot_y(-v))
        return left, right

    def dot_projector_camera(self) -> Camera:
        """True pose and intrinsics of the random-dot projector (between the cameras)."""
        return self._projector(self.world_from_rig() @ _trans(0.0, -0.02, 0.0))

    def sl_devices(self) -> tuple[Camera, Camera]:
        """True camera and projector of the structured-light rig (projector on the right)."""
        Wr = self.world_from_rig()
        v, b = np.radians(self.rig.vergence_deg) / 2, self.rig.baseline
        cam = self._camera(self.left, Wr @ _trans(-b / 2, 0, 0) @ rot_y(v))
        return cam, self._projector(Wr @ _trans(b / 2, 0, 0) @ rot_y(-v))

    def target(self) -> ChArUcoTarget:
        return self.calibration.target()


@dataclass
class _CaptureRun(Config):
    seed: int = option(0, range="[0, inf)", help="calibration poses, dots and sensor noise seed")
    object: str | None = option(None, help="name of the scanned object in the scene (its mesh "
                                           "sets the evaluation scale; none: 'object' if any)")


@dataclass
class SLCaptureConfig(RigConfig, _CaptureRun):
    """Everything ``scanamp capture structured-light`` reads: the rig (the right camera is
    the projector), the seed, the scanned object."""


@dataclass
class StereoCaptureConfig(RigConfig, _CaptureRun):
    """Everything ``scanamp capture stereo`` reads: the rig, the seed, the scanned object."""

    textureless: bool = option(False, help="give every object a constant material "
                                           "(passive stereo fails there)")
