"""Stereo and structured-light rigs on a turntable: configuration and geometry.

A rig looks at the turntable axis (world Z through the origin) from ``distance``
metres at ``elevation_deg``. The stereo rig has two cameras ``baseline`` apart,
each turned toward the centre by half the ``vergence_deg`` (toe-in), each with its
own intrinsics and distortion, and optionally a random-dot projector between them.
The structured-light rig replaces the right camera by a projector (an inverse
camera) ``baseline`` to the right. The object sits on the turntable, which turns
to each of ``stage_angles_deg`` (a real turntable reports its angle; the rig's
pose relative to the axis is calibrated from board views, never taken from here).

Configs are TOML (every key optional; defaults below); errors name file and field::

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

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from acquire.camera import Camera, look_at_cam_from_world
from acquire.sensor import Sensor
from acquire.targets import ChArUcoTarget
from core.files import read_toml, require
from core.validate import InputError, check_int

__all__ = ["RigConfig", "load_rig", "rot_z", "rot_y"]


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
class RigConfig:
    """All rig settings (see the module docstring for the meaning and defaults)."""

    width: int = 640
    height: int = 480
    fov_deg: float = 50.0
    left_dist: tuple = (0.02, -0.01, 0.0, 0.0, 0.0)
    left_focal_scale: float = 1.0
    left_principal_offset: tuple = (0.0, 0.0)
    right_dist: tuple = (-0.015, 0.005, 0.0, 0.0, 0.0)
    right_focal_scale: float = 1.01
    right_principal_offset: tuple = (2.0, -1.5)
    baseline: float = 0.08
    vergence_deg: float = 8.0
    distance: float = 0.45
    elevation_deg: float = 25.0
    aim_height: float = 0.06
    stage_angles_deg: tuple = (0.0, 90.0, 180.0, 270.0)
    working_range: tuple = (0.3, 0.65)
    projector_enabled: bool = True
    projector_width: int = 640
    projector_height: int = 480
    projector_fov_deg: float = 50.0
    projector_intensity: float = 0.12
    dot_density: float = 0.35
    dot_sigma_px: float = 0.7
    period_px: float = 16.0
    n_steps: int = 4
    calib_views: int = 10
    axis_views: int = 5
    board: dict = field(default_factory=lambda: {
        "squares_x": 7, "squares_y": 5, "square_length": 0.03, "marker_length": 0.022,
        "dictionary": "DICT_4X4_50"})
    supersample: int = 2
    ambient: float = 0.15
    sensor: dict = field(default_factory=dict)

    # -- geometry (true values: used to render, stored as ground truth) ----------------
    def world_from_rig(self) -> np.ndarray:
        el = np.radians(self.elevation_deg)
        aim = np.array([0.0, 0.0, self.aim_height])
        eye = aim + self.distance * np.array([0.0, -np.cos(el), np.sin(el)])
        return np.linalg.inv(look_at_cam_from_world(eye, aim))

    def _camera(self, side: str, world_from_cam: np.ndarray) -> Camera:
        f = 0.5 * self.width / np.tan(np.radians(self.fov_deg) / 2)
        scale = getattr(self, f"{side}_focal_scale")
        off = getattr(self, f"{side}_principal_offset")
        return Camera(self.width, self.height, f * scale, f * scale,
                      (self.width - 1) / 2 + off[0], (self.height - 1) / 2 + off[1],
                      np.asarray(getattr(self, f"{side}_dist"), float),
                      np.linalg.inv(world_from_cam))

    def stereo_cameras(self) -> tuple[Camera, Camera]:
        """True left and right cameras (world frame, turntable at angle 0)."""
        Wr = self.world_from_rig()
        v = np.radians(self.vergence_deg) / 2
        left = self._camera("left", Wr @ _trans(-self.baseline / 2, 0, 0) @ rot_y(v))
        right = self._camera("right", Wr @ _trans(self.baseline / 2, 0, 0) @ rot_y(-v))
        return left, right

    def dot_projector_camera(self) -> Camera:
        """True pose and intrinsics of the random-dot projector (between the cameras)."""
        f = 0.5 * self.projector_width / np.tan(np.radians(self.projector_fov_deg) / 2)
        Wp = self.world_from_rig() @ _trans(0.0, -0.02, 0.0)
        return Camera(self.projector_width, self.projector_height, f, f,
                      (self.projector_width - 1) / 2, (self.projector_height - 1) / 2,
                      np.zeros(5), np.linalg.inv(Wp))

    def sl_devices(self) -> tuple[Camera, Camera]:
        """True camera and projector of the structured-light rig (projector on the right)."""
        Wr = self.world_from_rig()
        v = np.radians(self.vergence_deg) / 2
        cam = self._camera("left", Wr @ _trans(-self.baseline / 2, 0, 0) @ rot_y(v))
        f = 0.5 * self.projector_width / np.tan(np.radians(self.projector_fov_deg) / 2)
        Wp = Wr @ _trans(self.baseline / 2, 0, 0) @ rot_y(-v)
        proj = Camera(self.projector_width, self.projector_height, f, f,
                      (self.projector_width - 1) / 2, (self.projector_height - 1) / 2 + 0.0,
                      np.zeros(5), np.linalg.inv(Wp))
        return cam, proj

    def target(self) -> ChArUcoTarget:
        return ChArUcoTarget(**self.board)

    def make_sensor(self) -> Sensor:
        return Sensor(**self.sensor)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


_TABLES = {
    "camera": {"width": ("width", int), "height": ("height", int), "fov_deg": ("fov_deg", float)},
    "left": {"dist": ("left_dist", list), "focal_scale": ("left_focal_scale", float),
             "principal_offset": ("left_principal_offset", list)},
    "right": {"dist": ("right_dist", list), "focal_scale": ("right_focal_scale", float),
              "principal_offset": ("right_principal_offset", list)},
    "rig": {"baseline": ("baseline", float), "vergence_deg": ("vergence_deg", float),
            "distance": ("distance", float), "elevation_deg": ("elevation_deg", float),
            "aim_height": ("aim_height", float), "stage_angles_deg": ("stage_angles_deg", list),
            "working_range": ("working_range", list)},
    "projector": {"enabled": ("projector_enabled", bool), "width": ("projector_width", int),
                  "height": ("projector_height", int), "fov_deg": ("projector_fov_deg", float),
                  "intensity": ("projector_intensity", float), "density": ("dot_density", float),
                  "dot_sigma_px": ("dot_sigma_px", float), "period_px": ("period_px", float),
                  "n_steps": ("n_steps", int)},
    "render": {"supersample": ("supersample", int), "ambient": ("ambient", float)},
}
_LIST_LEN = {"left_dist": 5, "right_dist": 5, "left_principal_offset": 2,
             "right_principal_offset": 2, "working_range": 2}


def load_rig(path: str | Path | None = None, **overrides) -> RigConfig:
    """Read a rig TOML (None = defaults); ``overrides`` replace fields after reading.

    Raises
    ------
    InputError
        Naming the file and the field (``rig.toml: rig.baseline: expected a number``).
    """
    cfg = RigConfig()
    if path is not None:
        data = read_toml(path)
        known = set(_TABLES) | {"calibration", "sensor"}
        for key in data:
            if key not in known:
                raise InputError(f"unknown table; expected one of {', '.join(sorted(known))}",
                                 path=path, field=key)
        for table, keys in _TABLES.items():
            t = require(data, table, dict, path=path, default={})
            for key in t:
                if key not in keys:
                    raise InputError(f"unknown key; expected one of {', '.join(sorted(keys))}",
                                     path=path, field=f"{table}.{key}")
            for key, (attr, kind) in keys.items():
                v = require(t, key, kind, path=path, prefix=table, default=None)
                if v is None:
                    continue
                if kind is list:
                    if not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                               for x in v) or (attr in _LIST_LEN and len(v) != _LIST_LEN[attr]):
                        n = _LIST_LEN.get(attr)
                        raise InputError(f"expected a list of {n or 'some'} numbers, got {v!r}",
                                         path=path, field=f"{table}.{key}")
                    v = tuple(float(x) for x in v)
                setattr(cfg, attr, v)
        cal = require(data, "calibration", dict, path=path, default={})
        board = dict(cfg.board)
        for key in cal:
            if key == "views":
                cfg.calib_views = require(cal, key, int, path=path, prefix="calibration")
            elif key == "axis_views":
                cfg.axis_views = require(cal, key, int, path=path, prefix="calibration")
            elif key in board:
                board[key] = require(cal, key, type(board[key]) if key != "dictionary" else str,
                                     path=path, prefix="calibration")
            else:
                raise InputError("unknown key", path=path, field=f"calibration.{key}")
        cfg.board = board
        cfg.sensor = dict(require(data, "sensor", dict, path=path, default={}))
    for k, v in overrides.items():
        setattr(cfg, k, v)
    try:
        _validate(cfg)
    except ValueError as exc:
        if path is None:
            raise
        raise InputError(str(exc), path=path) from None
    return cfg


def _validate(cfg: RigConfig):
    for name in ("width", "height", "projector_width", "projector_height", "supersample",
                 "calib_views", "axis_views", "n_steps"):
        check_int(getattr(cfg, name), name)
    for name in ("fov_deg", "baseline", "distance", "projector_fov_deg", "period_px"):
        if not getattr(cfg, name) > 0:
            raise ValueError(f"{name}: expected a positive number, got {getattr(cfg, name)!r}")
    if not 0 < cfg.working_range[0] < cfg.working_range[1]:
        raise ValueError(f"working_range: expected 0 < near < far, got {cfg.working_range}")
    if len(cfg.stage_angles_deg) == 0:
        raise ValueError("stage_angles_deg: expected at least one angle")
    if cfg.calib_views < 3:
        raise ValueError(f"calibration.views: expected at least 3, got {cfg.calib_views}")
    if cfg.axis_views < 3:
        raise ValueError(f"calibration.axis_views: expected at least 3, got {cfg.axis_views}")
    cfg.target()  # board checks
    cfg.make_sensor()
