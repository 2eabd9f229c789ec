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

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from acquire.camera import Camera, look_at_cam_from_world
from acquire.laser import LaserSheet
from acquire.sensor import Sensor
from acquire.targets import ChArUcoTarget, target_from_dict
from core.files import read_toml
from core.frames import rotation_about
from core.validate import InputError, check_choice, check_int, check_positive, check_range

__all__ = ["LaserRig", "load_rig"]


@dataclass
class LaserRig:
    """Every setting of a laser-triangulation capture (TOML table ``[rig]``).

    Angles in degrees, lengths in metres.
    """

    # camera
    width: int = 640
    height: int = 480
    fov_deg: float = 40.0
    distortion: tuple = (-0.04, 0.02, 0.0, 0.0, 0.0)
    working_distance: float = 0.40
    camera_elevation_deg: float = 15.0
    aim_height: float = 0.075
    # laser
    triangulation_angle_deg: float = 30.0
    laser_distance: float = 0.40
    laser_elevation_deg: float = 0.0
    fan_angle_deg: float = 40.0
    laser_thickness: float = 0.0005
    laser_power: float = 0.35
    speckle: float = 0.0
    ambient: float = 0.05
    # motion
    motion: str = "turntable"
    steps: int = 360
    step_deg: float = 1.0
    axis_center: tuple = (0.0, 0.0, 0.0)
    stage_direction: tuple = (0.0, 1.0, 0.0)
    stage_step: float = 0.001
    # calibration plan
    target: dict = field(default_factory=lambda: ChArUcoTarget(
        squares_x=9, squares_y=7, square_length=0.016, marker_length=0.012).to_dict())
    camera_views: int = 20
    # 8 stripe-on-board poses: over 8 calibrations the plane normal error is RMS 0.023,
    # worst 0.041 deg; with 4 poses 0.033, worst 0.055 (benchmarks/bench_laser_calibration.py)
    laser_views: int = 8
    axis_views: int = 9
    axis_span_deg: float = 90.0
    stage_views: int = 5
    calib_supersample: int = 3
    sensor: dict = field(default_factory=lambda: Sensor().to_dict())

    def __post_init__(self):
        for name in ("width", "height", "steps", "camera_views", "laser_views", "axis_views",
                     "stage_views", "calib_supersample"):
            setattr(self, name, check_int(getattr(self, name), name))
        check_range(self.fov_deg, "fov_deg", 1, 170)
        check_range(self.triangulation_angle_deg, "triangulation_angle_deg", 1, 89)
        check_range(self.fan_angle_deg, "fan_angle_deg", 1, 170)
        check_range(self.camera_elevation_deg, "camera_elevation_deg", -80, 80)
        check_range(self.laser_elevation_deg, "laser_elevation_deg", -80, 80)
        for name in ("working_distance", "laser_distance", "laser_thickness", "stage_step"):
            check_positive(getattr(self, name), name)
        check_positive(self.laser_power, "laser_power", allow_zero=True)
        check_positive(self.ambient, "ambient", allow_zero=True)
        check_range(self.speckle, "speckle", 0, 2)
        check_choice(self.motion, "motion", ("turntable", "stage"))
        if self.laser_views < 2:
            raise ValueError(f"laser_views: expected at least 2 (a plane needs two stripe "
                             f"lines), got {self.laser_views}")
        if len(self.distortion) != 5:
            raise ValueError(f"distortion: expected 5 values (k1, k2, p1, p2, k3), "
                             f"got {len(self.distortion)}")
        _ = self.target_obj, self.sensor_obj  # validate

    # -- derived objects ----------------------------------------------------------------
    @property
    def target_obj(self):
        return target_from_dict(self.target)

    @property
    def sensor_obj(self) -> Sensor:
        try:
            return Sensor.from_dict(self.sensor)
        except TypeError as exc:
            raise ValueError(f"sensor: {exc}") from None

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
                          self.laser_thickness, self.laser_power, None, self.speckle)

    @property
    def baseline(self) -> float:
        return float(np.linalg.norm(self.camera().center - self.laser().origin))

    def frame_positions(self) -> np.ndarray:
        """Stage reading per frame: turntable angle in degrees, or stage offset in metres."""
        if self.motion == "turntable":
            return np.arange(self.steps) * self.step_deg
        return np.arange(self.steps) * self.stage_step

    def world_from_object(self, position: float) -> np.ndarray:
        """Where the stage carries the object at a stage reading (degrees or metres)."""
        if self.motion == "turntable":
            return rotation_about([0, 0, 1], np.radians(position), self.axis_center)
        d = np.asarray(self.stage_direction, float)
        T = np.eye(4)
        T[:3, 3] = position * d / np.linalg.norm(d)
        return T

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        for k, v in d.items():
            if isinstance(v, tuple):
                d[k] = list(v)
        return d


_FIELDS = {f.name: f for f in dataclasses.fields(LaserRig)}


def load_rig(path: str | Path | None = None, *, overrides: dict | None = None) -> LaserRig:
    """Read a rig from TOML (table ``[rig]``, optional ``[sensor]`` and ``[target]``).

    Unknown keys and bad values raise InputError naming the file and field.
    ``overrides`` (``{"triangulation_angle_deg": 45}``) are applied last (study sweeps).
    """
    data: dict = {}
    if path is not None:
        raw = read_toml(path)
        rig = raw.get("rig", {})
        if not isinstance(rig, dict):
            raise InputError("expected a table", path=path, field="rig")
        data.update(rig)
        for sect in ("sensor", "target"):
            if sect in raw:
                if not isinstance(raw[sect], dict):
                    raise InputError("expected a table", path=path, field=sect)
                base = (Sensor().to_dict() if sect == "sensor"
                        else LaserRig().target)
                data[sect] = {**base, **raw[sect]}
        for key in raw:
            if key not in ("rig", "sensor", "target"):
                raise InputError("unknown table (expected rig, sensor, target)", path=path,
                                 field=key)
    data.update(overrides or {})
    for key, value in data.items():
        if key not in _FIELDS:
            raise InputError(f"unknown field (expected one of {', '.join(sorted(_FIELDS))})",
                             path=path, field=f"rig.{key}")
        if isinstance(value, list):
            data[key] = tuple(value)
    try:
        return LaserRig(**data)
    except (ValueError, TypeError) as exc:
        msg = str(exc)
        field_name = msg.split(":")[0] if ":" in msg else None
        raise InputError(msg.split(": ", 1)[-1] if field_name else msg, path=path,
                         field=f"rig.{field_name}" if field_name else None) from None
