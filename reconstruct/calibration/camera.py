"""Camera calibration from images of a planar target (ChArUco or chessboard).

Zhang's method as OpenCV implements it (``cv2.calibrateCamera``): detect the
target's corners in each image, match them to the corners' known positions on the
board, estimate intrinsics, distortion and one board pose per view by minimizing
the reprojection error. Used by every acquisition kind that has a camera (laser,
stereo, structured light); the target is any object of :mod:`acquire.targets`
(anything with ``detect(image) -> (ids, corners) | None`` and ``corner_points()``).

References
----------
Z. Zhang, "A flexible new technique for camera calibration", IEEE TPAMI 22(11),
2000, doi:10.1109/34.888718.
"""

from __future__ import annotations

import contextlib
import logging
from dataclasses import dataclass, field

import numpy as np

from acquire.camera import Camera
from core.validate import check_int

log = logging.getLogger(__name__)

__all__ = ["CameraCalibration", "calibrate_camera", "calibrate_camera_points", "detect_board",
           "to_gray", "board_pose", "bootstrap_cameras"]

DIST_MODELS = ("k1k2", "k1k2p1p2", "full")


@dataclass
class CameraCalibration:
    """Result of :func:`calibrate_camera`.

    Attributes
    ----------
    camera : acquire.camera.Camera
        Intrinsics and distortion; ``cam_from_world`` is the identity (the camera frame).
    rms : float
        RMS reprojection error over all used corners, pixels.
    per_view_errors : (m,) float64
        RMS reprojection error of each used view.
    used_views : list of int
        Indices (into the input images) of the views where the target was detected.
    cam_from_target : list of (4, 4) float64
        The board's pose in each used view.
    rejected_views : list of int
        Views where the target was not detected (too few corners).
    std_intrinsics : (9,) float64
        OpenCV's standard deviations of ``fx, fy, cx, cy, k1, k2, p1, p2, k3`` (from the
        residuals and the Jacobian; 0 for fixed parameters).
    object_points, image_points : list of (k, 3) / (k, 2) float64
        The corners used, per used view (for :func:`bootstrap_cameras`).
    flags : int
        The ``cv2.calibrateCamera`` flags used.
    """

    camera: Camera
    rms: float
    per_view_errors: np.ndarray
    used_views: list
    cam_from_target: list
    rejected_views: list = field(default_factory=list)
    std_intrinsics: np.ndarray = None
    object_points: list = None
    image_points: list = None
    flags: int = 0

    def to_dict(self) -> dict:
        d = {"camera": self.camera.to_dict(), "rms_px": float(self.rms),
             "per_view_rms_px": [float(e) for e in self.per_view_errors],
             "used_views": list(self.used_views),
             "rejected_views": list(self.rejected_views)}
        if self.std_intrinsics is not None:
            d["std_intrinsics"] = dict(zip(("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2",
                                            "k3"), map(float, self.std_intrinsics), strict=True))
        return d


@contextlib.contextmanager
def cv2_single_thread():
    """Run OpenCV on one thread inside: its calibration solvers sum over views in parallel,
    and the sums' order changes the last bits from run to run (same input, other bytes)."""
    import cv2

    before = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(before)


def to_gray(img: np.ndarray) -> np.ndarray:
    """uint8 grayscale of an RGB/gray uint8 or uint16 image."""
    import cv2

    if img.dtype == np.uint16:
        img = (img / 257).astype(np.uint8)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    return img


def detect_board(target, image: np.ndarray):
    """``(object_points (k, 3), image_points (k, 2), ids (k,))`` of ``target`` in an
    RGB/gray uint8/uint16 ``image`` (the target converts it to grey), or None where it is
    not detected. The one board detector of the calibrations."""
    det = target.detect(image)
    if det is None:
        return None
    ids, px = det
    return target.corner_points()[ids], px, ids


def _rt_to_T(rvec, tvec):
    import cv2

    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(np.asarray(rvec, float).reshape(3))[0]
    T[:3, 3] = np.asarray(tvec, float).reshape(3)
    return T


def board_pose(object_points: np.ndarray, pixels: np.ndarray, camera: Camera) -> np.ndarray:
    """``cam_from_target (4, 4)`` of a detected board, by PnP with the calibrated camera."""
    import cv2

    if len(object_points) < 4:
        raise ValueError(f"object_points: expected at least 4 corners, got {len(object_points)}")
    ok, rvec, tvec = cv2.solvePnP(object_points.astype(np.float64), pixels.astype(np.float64),
                                  camera.K, camera.dist, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        raise RuntimeError("board pose: solvePnP failed")
    rvec, tvec = cv2.solvePnPRefineLM(object_points.astype(np.float64),
                                      pixels.astype(np.float64), camera.K, camera.dist,
                                      rvec, tvec)
    return _rt_to_T(rvec, tvec)


def calibrate_camera(images, target, *, dist_model: str = "k1k2p1p2",
                     min_views: int = 3, min_corners: int = 8,
                     names: list[str] | None = None) -> CameraCalibration:
    """Calibrate a camera from images of a planar target.

    Parameters
    ----------
    images : sequence of (h, w) or (h, w, 3) uint8
        Views of the target (all the same size).
    target : ChArUcoTarget or ChessboardTarget
    dist_model : {'k1k2', 'k1k2p1p2', 'full'}
        Distortion parameters estimated (the others fixed at 0): radial only, radial
        plus tangential, or all five (k3 too; needs many well-spread views).
    min_views : int
        Views with a detected target needed, else RuntimeError.
    min_corners : int
        Corners a view needs to be used.
    names : list of str, optional
        Names of the images, for error messages.

    Returns
    -------
    CameraCalibration

    Raises
    ------
    ValueError
        Images of different sizes or dist_model unknown.
    RuntimeError
        Too few views with a detected target.
    """

    from core.validate import check_choice

    check_choice(dist_model, "dist_model", DIST_MODELS)
    images = list(images)
    if not images:
        raise ValueError("images: expected at least one image, got none")
    names = names or [f"image {i}" for i in range(len(images))]
    h, w = images[0].shape[:2]
    obj, img, used, rejected = [], [], [], []
    for i, im in enumerate(images):
        if im.shape[:2] != (h, w):
            raise ValueError(f"images: {names[i]} is {im.shape[1]}x{im.shape[0]}, "
                             f"expected {w}x{h} like the first")
        det = detect_board(target, im)
        if det is None or len(det[0]) < min_corners:
            rejected.append(i)
            continue
        obj.append(det[0].astype(np.float32))
        img.append(det[1].astype(np.float32).reshape(-1, 1, 2))
        used.append(i)
    if len(used) < min_views:
        bad = ", ".join(names[i] for i in rejected[:6]) + (" ..." if len(rejected) > 6 else "")
        raise RuntimeError(f"camera calibration: the target was detected in {len(used)} of "
                           f"{len(images)} views, need {min_views} (not detected: {bad})")
    if rejected:
        log.warning("camera calibration: target not detected in %s",
                    ", ".join(names[i] for i in rejected))
    cal = calibrate_camera_points(obj, img, (w, h), dist_model=dist_model, min_views=1)
    cal.used_views, cal.rejected_views = used, rejected
    return cal


def calibrate_camera_points(object_points, image_points, image_size, *,
                            dist_model: str = "k1k2p1p2", min_views: int = 3,
                            name: str = "camera") -> CameraCalibration:
    """Calibrate a camera (or a projector, as an inverse camera) from corner correspondences.

    The point-level core of :func:`calibrate_camera`, for callers that found the
    correspondences themselves (a stereo pair's board detections, a projector's decoded
    coordinates at the board corners).

    Parameters
    ----------
    object_points : list of (k_i, 3) float
        Target corners in the target frame, per view.
    image_points : list of (k_i, 2) float
        Their pixels in this device, per view.
    image_size : (int, int)
        ``(width, height)`` of the device's images.
    dist_model : {'k1k2', 'k1k2p1p2', 'full'}
        As for :func:`calibrate_camera`.
    min_views : int
        Views needed, else ValueError.
    name : str
        Names the device in error messages.

    Returns
    -------
    CameraCalibration
        ``used_views`` are all the given views.

    Raises
    ------
    ValueError
        Fewer than ``min_views`` views, or mismatched lists.
    """
    import cv2

    from core.validate import check_choice

    check_choice(dist_model, "dist_model", DIST_MODELS)
    if len(object_points) != len(image_points):
        raise ValueError(f"{name}: image_points: expected one array per view "
                         f"({len(object_points)}), got {len(image_points)}")
    if len(object_points) < max(int(min_views), 1):
        raise ValueError(f"{name}: expected the target in at least {min_views} views, got "
                         f"{len(object_points)}")
    w, h = (int(v) for v in image_size)
    obj = [np.asarray(o, np.float32).reshape(-1, 3) for o in object_points]
    img = [np.asarray(p, np.float32).reshape(-1, 1, 2) for p in image_points]
    flags = cv2.CALIB_FIX_K3
    if dist_model == "k1k2":
        flags |= cv2.CALIB_ZERO_TANGENT_DIST
    elif dist_model == "full":
        flags = 0
    # initial guess from a pinhole with a 50-degree field of view helps with few views
    f0 = 0.5 * w / np.tan(np.radians(25))
    K0 = np.array([[f0, 0, (w - 1) / 2], [0, f0, (h - 1) / 2], [0, 0, 1]])
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    with cv2_single_thread():
        rms, K, dist, rvecs, tvecs, std_in, _, per_view = cv2.calibrateCameraExtended(
            obj, img, (w, h), K0, np.zeros(5), flags=flags | cv2.CALIB_USE_INTRINSIC_GUESS,
            criteria=crit)
    cam = Camera(w, h, K[0, 0], K[1, 1], K[0, 2], K[1, 2], dist.ravel()[:5])
    poses = [_rt_to_T(r, t) for r, t in zip(rvecs, tvecs, strict=True)]
    return CameraCalibration(cam, float(rms), np.asarray(per_view, float).ravel(),
                             list(range(len(obj))), poses, [],
                             np.asarray(std_in, float).ravel()[:9],
                             [o.astype(np.float64) for o in obj],
                             [i.reshape(-1, 2).astype(np.float64) for i in img], int(flags))


def bootstrap_cameras(cal: CameraCalibration, rng: np.random.Generator, *,
                      draws: int = 32) -> list[Camera]:
    """Cameras recalibrated from the same corners plus fresh corner noise (a parametric
    bootstrap of the calibration).

    Each draw adds Gaussian noise of the calibration's own residual level (per-coordinate
    sigma ``rms / sqrt(2)``, the noise OpenCV's ``stdDeviationsIntrinsics`` assumes) to the
    detected corners and recalibrates. The spread of the returned cameras is the
    intrinsics' uncertainty with all its correlations (principal point with tangential
    distortion, focal length with k1), which per-parameter standard deviations lose.

    Parameters
    ----------
    cal : CameraCalibration
        From :func:`calibrate_camera`.
    rng : numpy.random.Generator
    draws : int
        Number of recalibrations.

    Returns
    -------
    list of Camera
        ``draws`` cameras (identity pose).
    """
    import cv2

    if cal.object_points is None or cal.image_points is None:
        raise ValueError("cal: expected a calibration that kept its corners "
                         "(from calibrate_camera)")
    draws = check_int(draws, "draws")
    c = cal.camera
    sigma = cal.rms / np.sqrt(2.0)
    obj = [o.astype(np.float32) for o in cal.object_points]
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-10)
    out = []
    for _ in range(int(draws)):
        img = [(p + rng.normal(0.0, sigma, p.shape)).astype(np.float32).reshape(-1, 1, 2)
               for p in cal.image_points]
        with cv2_single_thread():
            _, K, dist, *_ = cv2.calibrateCamera(
                obj, img, (c.width, c.height), c.K.copy(), c.dist.copy(),
                flags=cal.flags | cv2.CALIB_USE_INTRINSIC_GUESS, criteria=crit)
        out.append(Camera(c.width, c.height, K[0, 0], K[1, 1], K[0, 2], K[1, 2],
                          dist.ravel()[:5]))
    return out
