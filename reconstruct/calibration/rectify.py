"""A calibrated stereo pair and its rectification.

Conventions: ``R, T`` map left-camera coordinates into the right camera
(``right_from_left``, as ``cv2.stereoCalibrate`` returns them). The rectified left
camera is a distortion-free :class:`acquire.camera.Camera` whose frame is the left
camera frame rotated by ``R1``; disparity is ``x_left - x_right`` in rectified pixels.

>>> import numpy as np
>>> K = np.array([[100., 0, 31.5], [0, 100, 23.5], [0, 0, 1]])
>>> rect = rectify(StereoCalibration(K, np.zeros(5), K, np.zeros(5), np.eye(3),
...                                  np.array([-0.1, 0, 0]), (64, 48)))
>>> round(rect.focal * rect.baseline, 6)
10.0
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from acquire.camera import Camera
from core.validate import check_array, check_choice

__all__ = ["StereoCalibration", "Rectification", "rectify", "rectify_pair"]

_log = logging.getLogger(__name__)


@dataclass(eq=False)
class StereoCalibration:
    """Intrinsics and relative pose of a stereo pair (OpenCV conventions).

    Parameters
    ----------
    K1, K2 : (3, 3) float64
    D1, D2 : (5,) float64
        ``k1, k2, p1, p2, k3``.
    R : (3, 3) float64
    T : (3,) float64
        ``right_from_left``: ``x_right = R @ x_left + T`` (metres).
    image_size : (int, int)
        ``(width, height)``.
    rms : float, optional
        Reprojection RMS of the calibration, pixels.
    """

    K1: np.ndarray
    D1: np.ndarray
    K2: np.ndarray
    D2: np.ndarray
    R: np.ndarray
    T: np.ndarray
    image_size: tuple[int, int]
    rms: float | None = None

    def __post_init__(self):
        self.K1 = check_array(self.K1, "K1", shape=(3, 3))
        self.K2 = check_array(self.K2, "K2", shape=(3, 3))
        self.D1 = check_array(np.ravel(self.D1)[:5] if np.size(self.D1) >= 5 else self.D1, "D1",
                              shape=(5,))
        self.D2 = check_array(np.ravel(self.D2)[:5] if np.size(self.D2) >= 5 else self.D2, "D2",
                              shape=(5,))
        self.R = check_array(self.R, "R", shape=(3, 3))
        self.T = check_array(np.ravel(self.T), "T", shape=(3,))
        w, h = (int(v) for v in self.image_size)
        if w <= 0 or h <= 0:
            raise ValueError(f"image_size: expected positive (width, height), "
                             f"got {self.image_size}")
        self.image_size = (w, h)

    @property
    def baseline(self) -> float:
        """Distance between the camera centres, metres."""
        return float(np.linalg.norm(self.T))

    def cameras(self, world_from_left: np.ndarray | None = None) -> tuple[Camera, Camera]:
        """The two cameras, the left one at ``world_from_left`` (identity by default)."""
        Wl = np.eye(4) if world_from_left is None else np.asarray(world_from_left, float)
        left_from_world = np.linalg.inv(Wl)
        right_from_left = np.eye(4)
        right_from_left[:3, :3] = self.R
        right_from_left[:3, 3] = self.T
        w, h = self.image_size

        def cam(K, D, T):
            return Camera(w, h, K[0, 0], K[1, 1], K[0, 2], K[1, 2], D, T)

        return cam(self.K1, self.D1, left_from_world), \
            cam(self.K2, self.D2, right_from_left @ left_from_world)

    @classmethod
    def from_cameras(cls, left: Camera, right: Camera) -> StereoCalibration:
        """The calibration of two posed cameras (same image size)."""
        if (left.width, left.height) != (right.width, right.height):
            raise ValueError(f"right: expected the left image size {left.width}x{left.height}, "
                             f"got {right.width}x{right.height}")
        rfl = right.cam_from_world @ left.world_from_cam
        return cls(left.K, left.dist, right.K, right.dist, rfl[:3, :3], rfl[:3, 3],
                   (left.width, left.height))


@dataclass(eq=False)
class Rectification:
    """Rectifying transforms and remap tables of a calibrated pair.

    Attributes
    ----------
    R1, R2 : (3, 3)    rotations rectified_from_camera
    P1, P2 : (3, 4)    projections in the rectified frames
    Q : (4, 4)         disparity-to-depth matrix
    maps : tuple       (map1x, map1y, map2x, map2y) float32 remap tables
    calibration : StereoCalibration
    """

    R1: np.ndarray
    R2: np.ndarray
    P1: np.ndarray
    P2: np.ndarray
    Q: np.ndarray
    maps: tuple = field(repr=False)
    calibration: StereoCalibration = field(repr=False)

    @property
    def focal(self) -> float:
        return float(self.P1[0, 0])

    @property
    def baseline(self) -> float:
        """Rectified baseline (metres, positive)."""
        return float(abs(self.P2[0, 3] / self.P2[0, 0]))

    def left_camera(self, world_from_left: np.ndarray | None = None) -> Camera:
        """The rectified left camera (no distortion), posed in the world."""
        Wl = np.eye(4) if world_from_left is None else np.asarray(world_from_left, float)
        rect_from_left = np.eye(4)
        rect_from_left[:3, :3] = self.R1
        w, h = self.calibration.image_size
        P = self.P1
        return Camera(w, h, P[0, 0], P[1, 1], P[0, 2], P[1, 2], np.zeros(5),
                      rect_from_left @ np.linalg.inv(Wl))


def rectify(calibration: StereoCalibration, *, alpha: float = 0.0) -> Rectification:
    """Rectification of a calibrated pair (``cv2.stereoRectify`` + remap tables).

    ``alpha = 0`` keeps only valid pixels (zoomed in); 1 keeps every source pixel.
    """
    import cv2

    c = calibration
    R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(c.K1, c.D1, c.K2, c.D2, c.image_size, c.R, c.T,
                                                flags=cv2.CALIB_ZERO_DISPARITY, alpha=alpha)
    m1 = cv2.initUndistortRectifyMap(c.K1, c.D1, R1, P1, c.image_size, cv2.CV_32FC1)
    m2 = cv2.initUndistortRectifyMap(c.K2, c.D2, R2, P2, c.image_size, cv2.CV_32FC1)
    return Rectification(R1, R2, P1, P2, Q, (m1[0], m1[1], m2[0], m2[1]), c)


def rectify_pair(left: np.ndarray, right: np.ndarray, rect: Rectification, *,
                 interpolation: str = "linear") -> tuple[np.ndarray, np.ndarray]:
    """Remap a raw pair into the rectified frames (``interpolation``: linear or nearest)."""
    import cv2

    check_choice(interpolation, "interpolation", {"linear", "nearest"})
    w, h = rect.calibration.image_size
    for name, img in (("left", left), ("right", right)):
        if img.shape[:2] != (h, w):
            raise ValueError(f"{name}: expected an image of {w}x{h} (the calibration's "
                             f"image_size), got {img.shape[1]}x{img.shape[0]}")
    flag = cv2.INTER_LINEAR if interpolation == "linear" else cv2.INTER_NEAREST
    m = rect.maps
    return (cv2.remap(left, m[0], m[1], flag, borderMode=cv2.BORDER_CONSTANT),
            cv2.remap(right, m[2], m[3], flag, borderMode=cv2.BORDER_CONSTANT))
