"""Pinhole camera with OpenCV intrinsics and distortion.

Conventions (DESIGN.md): the camera frame is OpenCV's (x right, y down, z forward);
pixel centres sit at integer coordinates; distortion is OpenCV's five-parameter
model ``(k1, k2, p1, p2, k3)``; depth is z-depth in metres. Poses are named by
frames: ``cam_from_world`` maps world points into the camera frame.

>>> cam = Camera.look_at([0, -1, 0], [0, 0, 0], width=64, height=48, fov_deg=60)
>>> px, z = cam.project([[0.0, 0.0, 0.0]])
>>> px.round(6).tolist(), z.round(6).tolist()
([[31.5, 23.5]], [1.0])
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.frames import transform_points
from core.validate import check_array, check_int, check_positive

__all__ = ["Camera", "distort", "undistort", "look_at_cam_from_world", "frame_camera"]


def distort(xy: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Apply OpenCV distortion to normalized image coordinates.

    Parameters
    ----------
    xy : (n, 2) float64
        Undistorted normalized coordinates ``(X/Z, Y/Z)``.
    dist : (5,) float64
        ``k1, k2, p1, p2, k3``.
    """
    k1, k2, p1, p2, k3 = dist
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return np.stack([xd, yd], axis=1)


def undistort(xy_d: np.ndarray, dist: np.ndarray, *, iterations: int = 20,
              tol: float = 1e-14) -> np.ndarray:
    """Invert :func:`distort` by Newton's method (to ~1e-14 in normalized units).

    OpenCV's ``undistortPoints`` uses a fixed-point iteration that stops early for
    strong distortion; Newton with the analytic Jacobian converges quadratically.
    """
    k1, k2, p1, p2, k3 = dist
    xy = xy_d.copy()
    if not np.any(dist):
        return xy
    for _ in range(iterations):
        x, y = xy[:, 0], xy[:, 1]
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dr = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r2
        res = distort(xy, dist) - xy_d
        a = radial + 2.0 * x * x * dr + 2.0 * p1 * y + 6.0 * p2 * x
        b = 2.0 * x * y * dr + 2.0 * p1 * x + 2.0 * p2 * y
        d = radial + 2.0 * y * y * dr + 6.0 * p1 * y + 2.0 * p2 * x
        det = a * d - b * b
        det = np.where(np.abs(det) < 1e-300, 1e-300, det)
        step_x = (d * res[:, 0] - b * res[:, 1]) / det
        step_y = (a * res[:, 1] - b * res[:, 0]) / det
        xy[:, 0] -= step_x
        xy[:, 1] -= step_y
        if np.max(np.abs(step_x) + np.abs(step_y), initial=0.0) < tol:
            break
    return xy


def look_at_cam_from_world(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """``cam_from_world`` (4, 4) of an OpenCV camera at ``eye`` looking at ``target``.

    The image's "up" (-y) is as close to ``up`` as the viewing direction allows.
    """
    eye = check_array(eye, "eye", shape=(3,))
    target = check_array(target, "target", shape=(3,))
    up = check_array(up, "up", shape=(3,))
    z = target - eye
    n = np.linalg.norm(z)
    if n == 0:
        raise ValueError("target: expected a point different from eye, got the same point")
    z /= n
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:  # looking along up: pick another
        x = np.cross(z, [0.0, 1.0, 0.0] if abs(z[1]) < 0.9 else [1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])  # rows: camera axes in world
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = -R @ eye
    return T


@dataclass(eq=False)
class Camera:
    """A calibrated pinhole camera.

    Parameters
    ----------
    width, height : int
        Image size in pixels.
    fx, fy, cx, cy : float
        Intrinsics in pixels (OpenCV, pixel centres at integers).
    dist : (5,) float64
        ``k1, k2, p1, p2, k3``.
    cam_from_world : (4, 4) float64
        Rigid transform from world to camera frame.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))
    cam_from_world: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self):
        for name in ("width", "height"):
            setattr(self, name, check_int(getattr(self, name), name))
        for name in ("fx", "fy"):
            setattr(self, name, check_positive(getattr(self, name), name))
        self.cx = float(self.cx)
        self.cy = float(self.cy)
        self.dist = check_array(self.dist, "dist", shape=(5,)).copy()
        T = check_array(self.cam_from_world, "cam_from_world", shape=(4, 4)).copy()
        R = T[:3, :3]
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise ValueError("cam_from_world: expected a rigid transform (rotation + translation)")
        self.cam_from_world = T

    # -- construction -------------------------------------------------------------
    @classmethod
    def look_at(cls, eye, target, *, up=(0.0, 0.0, 1.0), width: int = 640, height: int = 480,
                fov_deg: float = 50.0, dist=None) -> Camera:
        """A camera at ``eye`` looking at ``target`` with horizontal field of view ``fov_deg``."""
        f = 0.5 * width / np.tan(np.radians(check_positive(fov_deg, "fov_deg")) / 2)
        return cls(width, height, f, f, (width - 1) / 2, (height - 1) / 2,
                   np.zeros(5) if dist is None else dist, look_at_cam_from_world(eye, target, up))

    def with_pose(self, cam_from_world: np.ndarray) -> Camera:
        """The same intrinsics at another pose."""
        return Camera(self.width, self.height, self.fx, self.fy, self.cx, self.cy,
                      self.dist, cam_from_world)

    # -- properties -----------------------------------------------------------------
    @property
    def K(self) -> np.ndarray:
        """Intrinsic matrix (3, 3)."""
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1.0]])

    @property
    def world_from_cam(self) -> np.ndarray:
        R, t = self.cam_from_world[:3, :3], self.cam_from_world[:3, 3]
        T = np.eye(4)
        T[:3, :3] = R.T
        T[:3, 3] = -R.T @ t
        return T

    @property
    def center(self) -> np.ndarray:
        """Camera centre in world coordinates (3,)."""
        return self.world_from_cam[:3, 3]

    # -- geometry -------------------------------------------------------------------
    def to_camera(self, points_world: np.ndarray) -> np.ndarray:
        """World points (n, 3) into the camera frame (n, 3)."""
        p = check_array(points_world, "points_world", shape=(None, 3))
        return transform_points(self.cam_from_world, p)

    def project(self, points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project world points through the distorted model.

        Returns
        -------
        pixels : (n, 2) float64
        z : (n,) float64
            Z-depth in the camera frame (points with z <= 0 give meaningless pixels).
        """
        pc = self.to_camera(points_world)
        z = pc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = pc[:, :2] / z[:, None]
        xy = distort(xy, self.dist)
        return np.stack([self.fx * xy[:, 0] + self.cx, self.fy * xy[:, 1] + self.cy], 1), z

    def normalized(self, pixels: np.ndarray) -> np.ndarray:
        """Undistorted normalized coordinates (n, 2) of pixels (n, 2)."""
        px = check_array(pixels, "pixels", shape=(None, 2))
        xy_d = np.stack([(px[:, 0] - self.cx) / self.fx, (px[:, 1] - self.cy) / self.fy], 1)
        return undistort(xy_d, self.dist)

    def undistort_pixels(self, pixels: np.ndarray) -> np.ndarray:
        """Pixels (n, 2) of the ideal (distortion-free) camera with the same K."""
        xy = self.normalized(pixels)
        return np.stack([self.fx * xy[:, 0] + self.cx, self.fy * xy[:, 1] + self.cy], 1)

    def unproject(self, pixels: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """World points (n, 3) at z-depth ``depth`` (n,) behind ``pixels`` (n, 2)."""
        xy = self.normalized(pixels)
        d = check_array(depth, "depth", shape=(len(xy),))
        pc = np.concatenate([xy * d[:, None], d[:, None]], axis=1)
        Tw = self.world_from_cam
        return transform_points(Tw, pc)

    def rays(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World rays through pixels: ``origins (n, 3)`` and ``directions (n, 3)``.

        Directions are scaled so that ``t = 1`` is z-depth 1 (``t_hit`` equals the
        z-depth of the hit), not unit length.
        """
        xy = self.normalized(pixels)
        dc = np.concatenate([xy, np.ones((len(xy), 1))], axis=1)
        Tw = self.world_from_cam
        d = dc @ Tw[:3, :3].T
        return np.broadcast_to(Tw[:3, 3], d.shape).copy(), d

    def pixel_grid(self, *, supersample: int = 1) -> np.ndarray:
        """Pixel sample positions (height*width*s*s, 2), row-major, s x s per pixel.

        With ``supersample = s`` the samples of pixel (u, v) sit at the centres of an
        s x s sub-grid of the pixel's square and are consecutive in the output.
        """
        s = check_int(supersample, "supersample")
        off = (np.arange(s) + 0.5) / s - 0.5
        v, u = np.mgrid[0:self.height, 0:self.width]
        ou, ov = np.meshgrid(off, off)
        uu = u[:, :, None, None] + ou[None, None]
        vv = v[:, :, None, None] + ov[None, None]
        return np.stack([uu.ravel(), vv.ravel()], axis=1).astype(np.float64)

    # -- serialization ----------------------------------------------------------------
    def to_dict(self) -> dict:
        """The camera as JSON-ready data (as stored in capture.json)."""
        return {"width": self.width, "height": self.height, "fx": self.fx, "fy": self.fy,
                "cx": self.cx, "cy": self.cy, "dist": self.dist.tolist(),
                "cam_from_world": self.cam_from_world.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> Camera:
        return cls(d["width"], d["height"], d["fx"], d["fy"], d["cx"], d["cy"],
                   np.asarray(d.get("dist", np.zeros(5)), float),
                   np.asarray(d.get("cam_from_world", np.eye(4)), float))


def frame_camera(points: np.ndarray, *, width: int = 640, height: int = 480,
                 fov_deg: float = 45.0, elevation_deg: float = 20.0,
                 azimuth_deg: float = -90.0, margin: float = 1.15) -> Camera:
    """A look-at camera that sees the bounding sphere of ``points (n, 3)`` whole.

    The camera sits ``elevation_deg`` above the horizon and ``azimuth_deg`` about +z
    (from +x), ``margin`` times as far as the sphere needs to fit the narrower field of
    view (``fov_deg`` is the horizontal one). Non-finite points are ignored; with none
    left, the unit cube is framed.

    >>> cam = frame_camera(np.array([[0.0, 0, 0], [1, 1, 1]]), width=64, height=48)
    >>> bool(cam.project(np.array([[0.0, 0, 0], [1, 1, 1]]))[1].all())
    True
    """
    p = np.asarray(points, float).reshape(-1, 3)
    p = p[np.all(np.isfinite(p), axis=1)]
    lo, hi = (p.min(0), p.max(0)) if len(p) else (-np.ones(3), np.ones(3))
    center = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-6)
    half_narrow = np.arctan(np.tan(np.radians(fov_deg) / 2) * min(1.0, height / width))
    dist = margin * radius / np.sin(half_narrow)
    el, az = np.radians(elevation_deg), np.radians(azimuth_deg)
    eye = center + dist * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return Camera.look_at(eye, center, width=width, height=height, fov_deg=fov_deg)
