"""The sheet-of-light rig: camera, line laser, turntable or linear stage, calibration plan.

Geometry (world frame, metres, Z up): the turntable axis is the world Z axis
through ``axis_center``; the scanned object sits on the platter. The camera looks at
the point ``aim_height`` up the axis from ``working_distance`` away, raised by
``camera_elevation_deg``. The laser stands ``laser_distance`` from the same aim point,
turned ``triangulation_angle_deg`` around the axis from the camera, and projects a
vertical sheet that contains the axis (the classic arrangement: every frame lights
one meridian of the object). The baseline (camera centre to laser origin) follows
from these knobs and is reported.

With a linear stage the object moves along ``stage_direction`` by ``stage_step``
per frame instead of turning.

The defaults are what a user would pick for a ~15 cm object: 640x480, a 40-degree
lens at 40 cm, a 30-degree triangulation angle, 360 steps of 1 degree.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acquire.camera import Camera, look_at_cam_from_world
from acquire.laser.sheet import LaserSheet
from acquire.render.speckle import grain_px
from acquire.sensor import Sensor
from acquire.targets import ChArUcoTarget, target_from_dict
from core.config import Config, option
from core.frames import rotation_about

__all__ = ["LaserRig", "LaserCaptureConfig"]


_DEFAULT_TARGET = ChArUcoTarget(squares_x=9, squares_y=7, square_length=0.016,
                                marker_length=0.012).to_dict()


@dataclass
class LaserRig(Config):
    """The geometry, motion and calibration plan of a laser-triangulation rig (TOML table
    ``[rig]``). Angles in degrees, lengths in metres."""

    # camera
    width: int = option(640, unit="px", range="[16, 16384]", help="image width")
    height: int = option(480, unit="px", range="[16, 16384]", help="image height")
    fov_deg: float = option(40.0, unit="deg", range="[1, 170]", help="horizontal field of view")
    distortion: tuple[float, float, float, float, float] = option(
        (-0.04, 0.02, 0.0, 0.0, 0.0), help="lens distortion k1, k2, p1, p2, k3 (OpenCV model)")
    working_distance: float = option(0.40, unit="m", range="(0, inf)",
                                     help="camera to the aim point on the axis")
    camera_elevation_deg: float = option(15.0, unit="deg", range="[-80, 80]",
                                         help="camera raised above the aim point")
    aim_height: float = option(0.075, unit="m", range="(-inf, inf)",
                               help="aim point up the turntable axis")
    # laser
    triangulation_angle_deg: float = option(30.0, unit="deg", range="[1, 89]",
                                            help="laser turned about the axis from the camera")
    laser_distance: float = option(0.40, unit="m", range="(0, inf)",
                                   help="laser origin to the aim point")
    laser_elevation_deg: float = option(0.0, unit="deg", range="[-80, 80]",
                                        help="laser raised above the aim point")
    fan_angle_deg: float = option(40.0, unit="deg", range="[1, 170]", help="laser fan angle")
    laser_thickness: float = option(0.0005, unit="m", range="(0, inf)",
                                    help="sheet thickness (Gaussian 1/e^2 width)")
    laser_power: float = option(0.35, range="[0, inf)", help="peak irradiance of the sheet")
    speckle: float = option(0.0, range="[0, 2]", help="speckle contrast of the stripe")
    wavelength_nm: float = option(650.0, unit="nm", range="(0, inf)",
                                  help="laser wavelength (the speckle grain)")
    f_number: float = option(4.0, range="(0, inf)", help="camera lens f-number (speckle grain)")
    pixel_pitch_um: float = option(3.45, unit="um", range="(0, inf)",
                                   help="sensor pixel pitch (the speckle grain in pixels)")
    independent_speckle: bool = option(False, help="speckle as independent pixels instead "
                                                   "of grains of the lens's Airy disc")
    ambient: float = option(0.05, range="[0, inf)", help="ambient light level")
    bounces: int = option(0, range="[0, 1]",
                          help="1: the stripe also returns by one bounce off glossy surfaces "
                               "(ghost stripes on shiny concave parts; slower)")
    # motion
    motion: str = option("turntable", choices=("turntable", "stage"),
                         help="what carries the object between frames")
    steps: int = option(360, range="[1, 100000]", help="frames of the scan")
    step_deg: float | None = option(None, unit="deg", range="(0, 360]",
                                    help="turntable step per frame (none: 360 / steps)")
    axis_center: tuple[float, float, float] = option((0.0, 0.0, 0.0), unit="m",
                                                     help="a point on the turntable axis")
    stage_direction: tuple[float, float, float] = option(
        (0.0, 1.0, 0.0), help="linear stage direction (motion = stage)")
    stage_step: float = option(0.001, unit="m", range="(0, inf)",
                               help="linear stage step per frame")
    # calibration plan
    camera_views: int = option(20, range="[3, 1000]", help="board views for the camera")
    # 8 stripe-on-board poses: over 8 calibrations the plane normal error is RMS 0.023,
    # worst 0.041 deg; with 4 poses 0.033, worst 0.055 (benchmarks/bench_laser_calibration.py)
    laser_views: int = option(8, range="[2, 1000]",
                              help="board poses under the laser (a plane needs two lines)")
    axis_views: int = option(9, range="[3, 1000]", help="board views for the turntable axis")
    axis_span_deg: float = option(90.0, unit="deg", range="(0, 360]",
                                  help="turntable span of the axis views")
    stage_views: int = option(5, range="[2, 1000]", help="board views for the stage direction")
    calib_supersample: int = option(3, range="[1, 8]",
                                    help="supersampling of the calibration renders")

    @property
    def turntable_step_deg(self) -> float:
        """The turntable step: ``step_deg``, or a full turn over ``steps`` when unset."""
        return 360.0 / self.steps if self.step_deg is None else float(self.step_deg)

    # -- derived objects ----------------------------------------------------------------
    @property
    def aim(self) -> np.ndarray:
        return np.asarray(self.axis_center, float) + [0.0, 0.0, self.aim_height]

    def camera(self) -> Camera:
        """The true camera at its home pose (frame 0)."""
        el = np.radians(self.camera_elevation_deg)
        eye = self.aim + self.working_distance * np.array([np.cos(el), 0.0, np.sin(el)])
        f = 0.5 * self.width / np.tan(np.radians(self.fov_deg) / 2)
        return Camera(self.width, self.height, f, f, (self.width - 1) / 2,
                      (self.height - 1) / 2, np.asarray(self.distortion, float),
                      look_at_cam_from_world(eye, self.aim))

    def laser(self) -> LaserSheet:
        """The true laser at frame 0: a vertical sheet through the turntable axis."""
        th = np.radians(self.triangulation_angle_deg)
        el = np.radians(self.laser_elevation_deg)
        origin = self.aim + self.laser_distance * np.array(
            [np.cos(th) * np.cos(el), np.sin(th) * np.cos(el), np.sin(el)])
        normal = np.array([-np.sin(th), np.cos(th), 0.0])
        return LaserSheet(origin, normal, self.aim - origin, np.radians(self.fan_angle_deg),
                          self.laser_thickness, self.laser_power, None, self.speckle,
                          0.0 if self.independent_speckle else grain_px(
                              self.wavelength_nm, self.f_number, self.pixel_pitch_um))

    @property
    def baseline(self) -> float:
        return float(np.linalg.norm(self.camera().center - self.laser().origin))

    def frame_positions(self) -> np.ndarray:
        """Stage reading per frame: turntable angle in degrees, or stage offset in metres."""
        if self.motion == "turntable":
            return np.arange(self.steps) * self.turntable_step_deg
        return np.arange(self.steps) * self.stage_step

    def world_from_object(self, position: float) -> np.ndarray:
        """Where the stage carries the object at a stage reading (degrees or metres)."""
        if self.motion == "turntable":
            return rotation_about([0, 0, 1], np.radians(position), self.axis_center)
        d = np.asarray(self.stage_direction, float)
        T = np.eye(4)
        T[:3, 3] = position * d / np.linalg.norm(d)
        return T


@dataclass
class LaserCaptureConfig(Config):
    """Everything ``scanamp capture laser`` reads: the rig, its sensor, the calibration
    board (TOML tables ``[rig]``, ``[sensor]``, ``[target]``), the seed.

    A ``[target]`` table of the default board's type (or without ``type``) fills its
    missing keys from the default board.
    """

    rig: LaserRig = option(default_factory=LaserRig, help="rig geometry, motion, calibration")
    sensor: Sensor = option(default_factory=Sensor, help="the camera's sensor")
    target: dict = option(default_factory=lambda: dict(_DEFAULT_TARGET), flag=False,
                          help="calibration board (acquire.targets fields, with 'type')")
    seed: int = option(0, range="[0, inf)", help="sensor noise and calibration poses seed")
    gt_depth: bool = option(False, help="also write each frame's ground-truth z-depth "
                                        "(gt/depth_*.npy)")

    def __post_init__(self):
        super().__post_init__()
        if self.target.get("type", _DEFAULT_TARGET["type"]) == _DEFAULT_TARGET["type"]:
            object.__setattr__(self, "target", {**_DEFAULT_TARGET, **self.target})
        target_from_dict(self.target)  # ValueError "target...: ..." on a bad board

    @property
    def target_obj(self):
        return target_from_dict(self.target)
