"""Calibration of a stereo pair (or camera + projector) and of a turntable axis.

Each device's intrinsics come from the project's camera calibration
(:func:`reconstruct.calibration.camera.calibrate_camera_points`, Zhang's method, shared with
the laser scanner); ``cv2.stereoCalibrate`` then refines both jointly and gives the
pair's relative pose. The turntable frame comes from a board on the turntable seen at
known stage angles: completely when the board's mount on the platter is known
(:func:`calibrate_turntable_mount`), up to its origin height and heading otherwise
(:func:`calibrate_turntable_axis`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from core.frames import transform_points
from core.validate import InputError, check_array
from reconstruct.calibration.camera import (
    calibrate_camera_points,
    cv2_single_thread,
    detect_board,
)
from reconstruct.calibration.rectify import StereoCalibration
from reconstruct.calibration.turntable import fit_axis

__all__ = ["PairViews", "detect_pair_views", "calibrate_pair", "calibrate_turntable_axis",
           "calibrate_turntable_mount", "world_from_cam_at"]

_log = logging.getLogger(__name__)


@dataclass
class PairViews:
    """Board detections in a series of image pairs (the inputs of :func:`calibrate_pair`).

    ``obj1, img1`` / ``obj2, img2``: each device's detections (object and image points per
    view); ``common``: ``(object, left, right)`` points of the corners both saw in the
    same view; ``missed``: names of the images where the board was not detected;
    ``image_size``: ``(width, height)``.
    """

    obj1: list = field(default_factory=list)
    img1: list = field(default_factory=list)
    obj2: list = field(default_factory=list)
    img2: list = field(default_factory=list)
    common: list = field(default_factory=list)
    missed: list = field(default_factory=list)
    image_size: tuple[int, int] | None = None


def detect_pair_views(target, pairs, *, min_common: int = 6) -> PairViews:
    """Detect ``target`` in each ``(name_left, left, name_right, right)`` of ``pairs``.

    Images of a pair must have one size (InputError naming the right image otherwise);
    a view joins ``common`` when both images show at least ``min_common`` of the same
    corners.
    """
    views = PairViews()
    for name_l, L, name_r, R in pairs:
        if L.shape[:2] != R.shape[:2]:
            raise InputError(f"left and right images differ in size ({L.shape[1]}x{L.shape[0]} "
                             f"vs {R.shape[1]}x{R.shape[0]})", path=name_r)
        if views.image_size is not None and views.image_size != (L.shape[1], L.shape[0]):
            raise InputError(f"image size {L.shape[1]}x{L.shape[0]} differs from the first "
                             f"pair's {views.image_size[0]}x{views.image_size[1]}", path=name_l)
        views.image_size = (L.shape[1], L.shape[0])
        dl, dr = detect_board(target, L), detect_board(target, R)
        for name, det, obj, img in ((name_l, dl, views.obj1, views.img1),
                                    (name_r, dr, views.obj2, views.img2)):
            if det is None:
                views.missed.append(str(name))
            else:
                obj.append(det[0])
                img.append(det[1])
        if dl is not None and dr is not None:
            ids = np.intersect1d(dl[2], dr[2])
            if len(ids) >= min_common:
                il = np.searchsorted(dl[2], ids)
                ir = np.searchsorted(dr[2], ids)
                views.common.append((dl[0][il], dl[1][il], dr[1][ir]))
    return views


def calibrate_pair(obj1: list, img1: list, obj2: list, img2: list, common: list,
                   image_size: tuple[int, int], *, image_size2: tuple[int, int] | None = None,
                   dist_model: str = "k1k2", refine_intrinsics: bool = True
                   ) -> tuple[StereoCalibration, dict]:
    """Calibrate two devices from board views.

    Parameters
    ----------
    obj1, img1 : lists of (k, 3), (k, 2)
        Views of device 1 (all its detections, for its intrinsics).
    obj2, img2 : lists
        Views of device 2.
    common : list of ((k, 3), (k, 2), (k, 2))
        Board corners seen by both in the same view: object points and the two
        image points (for ``cv2.stereoCalibrate``).
    image_size, image_size2 : (width, height)
        Image sizes (the second device may differ, e.g. a projector).
    dist_model : {'k1k2', 'k1k2p1p2', 'full'}
        Distortion parameters estimated for each device (see
        :func:`reconstruct.calibration.camera.calibrate_camera_points`). The default
        (radial only) fits lenses without decentring; tangential terms trade off
        against the principal point when the views are few.
    refine_intrinsics : bool
        Refine both devices' intrinsics in ``cv2.stereoCalibrate`` (from their single
        calibrations) instead of keeping them fixed.

    Returns
    -------
    StereoCalibration, dict
        The calibration (``image_size`` of device 1; device 2's intrinsics refer to
        ``image_size2``) and a report: per-device RMS and the stereo RMS.
    """
    import cv2

    size2 = image_size if image_size2 is None else image_size2
    c1 = calibrate_camera_points(obj1, img1, image_size, dist_model=dist_model, name="camera 1")
    c2 = calibrate_camera_points(obj2, img2, size2, dist_model=dist_model, name="camera 2")
    K1, D1, rms1 = c1.camera.K, c1.camera.dist, c1.rms
    K2, D2, rms2 = c2.camera.K, c2.camera.dist, c2.rms
    if len(common) < 3:
        raise ValueError(f"common: expected the board seen by both devices in at least 3 "
                         f"views, got {len(common)}")
    op = [np.asarray(c[0], np.float32).reshape(-1, 1, 3) for c in common]
    p1 = [np.asarray(c[1], np.float32).reshape(-1, 1, 2) for c in common]
    p2 = [np.asarray(c[2], np.float32).reshape(-1, 1, 2) for c in common]
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    if refine_intrinsics:
        # both devices see the same board pose in a common view: estimating everything
        # jointly pins focal lengths and principal points far better than each device
        # alone (measured: baseline error 0.6 % -> 0.3 %, right fx 0.35 % -> 0.04 %)
        flags = cv2.CALIB_USE_INTRINSIC_GUESS
        flags |= {"k1k2": cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3,
                  "k1k2p1p2": cv2.CALIB_FIX_K3, "full": 0}[dist_model]
    else:
        flags = cv2.CALIB_FIX_INTRINSIC
    with cv2_single_thread():
        rms, K1, D1, K2, D2, R, T, _, _ = cv2.stereoCalibrate(
            op, p1, p2, K1.copy(), D1.copy(), K2.copy(), D2.copy(), tuple(image_size),
            flags=flags, criteria=crit)
    calib = StereoCalibration(K1, D1.ravel()[:5], K2, D2.ravel()[:5], R, T.ravel(),
                              tuple(image_size), rms=float(rms))
    return calib, {"rms_1": rms1, "rms_2": rms2, "rms_stereo": float(rms),
                   "views": len(common)}


def calibrate_turntable_axis(object_points: list, image_points: list, angles_deg: list,
                             K: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, dict]:
    """Turntable frame from a board fixed on the turntable seen at several stage angles.

    The board's pose at stage angle ``a_i`` is ``cam_from_table @ Rz(a_i) @ table_from_board``.
    The relative rotations between views share the turntable axis; board corners
    circle around it. Returns ``table_from_cam (4, 4)``: the table frame has Z on the
    axis (oriented so the stage angle turns counter-clockwise about +Z), its origin on
    the axis at the height of the board's origin, and X toward the board at angle 0.

    Parameters
    ----------
    object_points, image_points : lists per view of (k, 3), (k, 2)
    angles_deg : list of float
        Stage angle of each view (as the turntable reports it).
    K, D : camera intrinsics and distortion

    Returns
    -------
    table_from_cam : (4, 4)
    info : dict  (``angle_rms_deg``: measured vs reported rotation angles)
    """
    import cv2

    if len(object_points) < 3:
        raise ValueError(f"axis views: expected the board in at least 3 views, got "
                         f"{len(object_points)}")
    Rs, ts = [], []
    for op, ip in zip(object_points, image_points, strict=True):
        ok, rvec, tvec = cv2.solvePnP(np.asarray(op, np.float64), np.asarray(ip, np.float64),
                                      K, D, flags=cv2.SOLVEPNP_ITERATIVE)
        if not ok:
            raise RuntimeError("solvePnP failed on an axis calibration view")
        Rs.append(cv2.Rodrigues(rvec)[0])
        ts.append(tvec.ravel())
    a = np.radians(np.asarray(angles_deg, float))
    n, c = fit_axis(Rs, ts, a)  # the linear start, refined below
    # measured rotation angles about n vs reported
    meas = []
    for i in range(len(Rs)):
        rv = cv2.Rodrigues(Rs[i] @ Rs[0].T)[0].ravel()
        meas.append(np.degrees(rv @ n))
    err = np.asarray(meas) - np.degrees(a - a[0])
    # table frame: z = n, x = from the axis toward the board origin at angle 0 (perp. part)
    v = ts[0] - c
    x = v - (v @ n) * n
    if np.linalg.norm(x) < 1e-9:
        x = np.cross(n, [1.0, 0, 0])
    x /= np.linalg.norm(x)
    y = np.cross(n, x)
    cam_from_table = np.eye(4)
    cam_from_table[:3, :3] = np.stack([x, y, n], axis=1)
    cam_from_table[:3, 3] = c
    cam_from_table = _refine_axis(cam_from_table, Rs[0], ts[0], object_points, image_points, a,
                                  K, D)
    return np.linalg.inv(cam_from_table), {"angle_rms_deg": float(np.sqrt(np.mean(err**2))),
                                           "views": len(Rs)}


def calibrate_turntable_mount(object_points: list, image_points: list, angles_deg: list,
                              table_from_target: np.ndarray, K: np.ndarray, D: np.ndarray
                              ) -> tuple[np.ndarray, dict]:
    """Turntable frame from a board mounted at a known place on the turntable.

    The board sits in a jig at ``table_from_target`` (stage angle 0), so at stage angle
    ``a_i`` its corners are at ``Rz(a_i) @ table_from_target @ p`` in the turntable frame:
    all views together form one rigid, non-planar 3-D target, and ``cam_from_table`` is
    a single PnP over all of them (initialised from the first view, refined by
    Levenberg-Marquardt). Unlike :func:`calibrate_turntable_axis` this fixes the whole
    frame -- origin on the platter, heading -- so a reconstruction lands in the world
    frame the turntable defines, with no registration to anything.

    Parameters
    ----------
    object_points, image_points : lists per view of (k, 3), (k, 2)
    angles_deg : list of float
        Stage angle of each view (as the turntable reports it).
    table_from_target : (4, 4)
        The board's mount on the turntable at stage angle 0.
    K, D : camera intrinsics and distortion

    Returns
    -------
    table_from_cam : (4, 4)
    info : dict  (``rms_px``: reprojection RMS over all views; ``views``)
    """
    import cv2

    Ttb = check_array(table_from_target, "table_from_target", shape=(4, 4))
    if len(object_points) < 1:
        raise ValueError(f"axis views: expected the board in at least 1 view, got "
                         f"{len(object_points)}")
    P, px = [], []
    for op, ip, a in zip(object_points, image_points, angles_deg, strict=True):
        Rz = np.eye(4)
        Rz[:3, :3] = _rz(np.radians(a))
        T = Rz @ Ttb
        P.append(transform_points(T, op))
        px.append(np.asarray(ip, np.float64))
    ok, rvec, tvec = cv2.solvePnP(np.asarray(object_points[0], np.float64), px[0], K, D,
                                  flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        raise RuntimeError("solvePnP failed on the first axis calibration view")
    cfb = np.eye(4)
    cfb[:3, :3], cfb[:3, 3] = cv2.Rodrigues(rvec)[0], tvec.ravel()
    Rz0 = np.eye(4)
    Rz0[:3, :3] = _rz(np.radians(angles_deg[0]))
    cft = cfb @ np.linalg.inv(Rz0 @ Ttb)
    P, px = np.concatenate(P), np.concatenate(px)
    rvec, tvec = cv2.solvePnPRefineLM(P, px, K, D, cv2.Rodrigues(cft[:3, :3])[0],
                                      cft[:3, 3].copy(),
                                      criteria=(cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS,
                                                100, 1e-12))
    proj, _ = cv2.projectPoints(P, rvec, tvec, K, D)
    rms = float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - px) ** 2, axis=1))))
    cft = np.eye(4)
    cft[:3, :3], cft[:3, 3] = cv2.Rodrigues(rvec)[0], tvec.ravel()
    return np.linalg.inv(cft), {"rms_px": rms, "views": len(object_points), "method": "mount"}


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def _refine_axis(cam_from_table, R0, t0, object_points, image_points, angles, K, D):
    """Minimise the reprojection error of ``cam_from_table @ Rz(a_i) @ table_from_board``
    over both transforms (the stage angles are known)."""
    import cv2
    from scipy.optimize import least_squares

    table_from_cam = np.linalg.inv(cam_from_table)
    # table_from_board at angle 0: Rz(-a0) @ table_from_cam @ cam_from_board_0
    cfb = np.eye(4)
    cfb[:3, :3], cfb[:3, 3] = R0, t0
    tfb = np.eye(4)
    tfb[:3, :3] = _rz(-angles[0])
    tfb = tfb @ table_from_cam @ cfb

    def pack(T):
        return np.concatenate([cv2.Rodrigues(T[:3, :3])[0].ravel(), T[:3, 3]])

    def unpack(p):
        T = np.eye(4)
        T[:3, :3] = cv2.Rodrigues(p[:3])[0]
        T[:3, 3] = p[3:6]
        return T

    def resid(p):
        Tct, Ttb = unpack(p[:6]), unpack(p[6:])
        out = []
        for op, ip, a in zip(object_points, image_points, angles, strict=True):
            Rz = np.eye(4)
            Rz[:3, :3] = _rz(a)
            T = Tct @ Rz @ Ttb
            proj, _ = cv2.projectPoints(np.asarray(op, np.float64), cv2.Rodrigues(T[:3, :3])[0],
                                        T[:3, 3], K, D)
            out.append((proj.reshape(-1, 2) - np.asarray(ip, np.float64)).ravel())
        return np.concatenate(out)

    p0 = np.concatenate([pack(cam_from_table), pack(tfb)])
    sol = least_squares(resid, p0, method="trf", x_scale="jac")
    return unpack(sol.x[:6])


def world_from_cam_at(table_from_cam: np.ndarray, angle_deg: float) -> np.ndarray:
    """``world_from_cam`` at a stage angle, world = table frame with the object at angle 0.

    The object turned by ``a``: a point seen by the camera maps back to its angle-0
    position by ``Rz(-a)``.
    """
    c, s = np.cos(np.radians(-angle_deg)), np.sin(np.radians(-angle_deg))
    Rz = np.eye(4)
    Rz[:2, :2] = [[c, -s], [s, c]]
    return Rz @ table_from_cam
