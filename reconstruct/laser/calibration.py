"""Laser-plane, turntable-axis and stage-direction calibration from target images.

All results are in the camera frame of the calibrated camera (OpenCV axes).

Laser plane: for each pose of a planar target crossing the sheet, the laser-off image
gives the board's pose (PnP), the laser-on image the stripe; the stripe pixels'
rays meet the board's plane in 3-D points of the sheet; one plane is fitted (SVD)
to the points of all poses, after rejecting points farther than 3 robust sigmas.
Two poses suffice (two distinct lines span the plane); more average the noise.

Turntable axis: the board stands on the platter and is imaged at several turntable
readings ``phi_k``. Its poses satisfy ``cam_from_target_k = A(phi_k - phi_0) @
cam_from_target_0`` where ``A(phi)`` turns by ``phi`` about the axis. A linear
estimate (axis from the relative rotations, point from ``(I - R) c = t_k - R t_0``)
starts a least-squares adjustment of all corner reprojections over the axis, its
point and the board's pose at reading 0, with the readings as known.

Linear stage: the board's translation is linear in the stage reading; the slope is
the stage direction (its norm checks the stage's scale).
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np

from acquire.camera import Camera
from core.frames import rotation_about, transform_points
from reconstruct.calibration.camera import board_pose, detect_board
from reconstruct.calibration.turntable import fit_axis
from reconstruct.laser.stripe import StripeOptions, detect_peaks

log = logging.getLogger(__name__)

__all__ = ["fit_plane", "intersect_rays_plane", "pixel_rays", "LaserPlaneCalibration",
           "calibrate_laser_plane", "refit_laser_plane", "AxisCalibration",
           "calibrate_turntable_axis",
           "calibrate_stage"]


def fit_plane(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares plane ``(n (3,), d)`` with ``n . x = d`` through ``points (n, 3)``."""
    c = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - c, full_matrices=False)
    n = vt[2]
    return n, float(n @ c)


def pixel_rays(camera: Camera, pixels: np.ndarray) -> np.ndarray:
    """Camera-frame ray directions ``(n, 3)`` (z = 1) through (distorted) ``pixels (n, 2)``."""
    xy = camera.normalized(pixels)
    return np.concatenate([xy, np.ones((len(xy), 1))], axis=1)


def intersect_rays_plane(directions: np.ndarray, plane: np.ndarray,
                         origin: np.ndarray | None = None) -> np.ndarray:
    """Points ``(n, 3)`` where rays ``origin + t * directions`` meet ``plane (4,)``
    (``n . x = d``); NaN for rays parallel to the plane."""
    n, d = np.asarray(plane[:3], float), float(plane[3])
    o = np.zeros(3) if origin is None else np.asarray(origin, float)
    den = directions @ n
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (d - o @ n) / den
    t = np.where(np.abs(den) > 1e-12, t, np.nan)
    return o + t[:, None] * directions


@dataclass
class LaserPlaneCalibration:
    """The sheet's plane in the camera frame and how well the stripe points fit it.

    Attributes
    ----------
    plane : (4,) float64            ``(nx, ny, nz, d)``, ``n . x = d``, unit n, d > 0
    rms : float                     RMS distance of the inliers to the plane, metres
    n_points : int                  inliers used
    used_views : list of int        poses whose board and stripe were both found
    rejected_views : list of int
    per_view_rms : list of float    RMS distance (m) of each used pose's points to the plane
    jackknife : (k, 4) float64      the plane refitted leaving out each used pose in turn
                                    (its spread estimates the plane's uncertainty)
    observations : list of tuple    per used pose: board corners ``(k, 3)``, their pixels
                                    ``(k, 2)`` and the stripe pixels ``(m, 2)`` used, to
                                    refit the plane under another camera
                                    (:func:`refit_laser_plane`)
    board_size : (2,) float64       the target's squares area (width, height), metres
    """

    plane: np.ndarray
    rms: float
    n_points: int
    used_views: list
    rejected_views: list
    per_view_rms: list = None
    jackknife: np.ndarray = None
    observations: list = None
    board_size: tuple = None

    def to_dict(self) -> dict:
        return {"plane": self.plane.tolist(), "rms_m": self.rms, "n_points": self.n_points,
                "used_views": self.used_views, "rejected_views": self.rejected_views,
                "per_view_rms_m": self.per_view_rms}


def _bright_around(off: np.ndarray, rows: np.ndarray, cols: np.ndarray, half: int = 3,
                   floor: float = 40.0) -> np.ndarray:
    """True where the laser-off image is bright (not a black square or marker bit) within
    ``half`` pixels of the stripe: there the on/off ratio is a clean laser profile."""
    h, w = off.shape
    c = np.round(cols).astype(int)
    ok = (c - half >= 0) & (c + half < w)
    out = np.zeros(len(rows), bool)
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return out
    win = np.stack([off[rows[idx], c[idx] + j] for j in range(-half, half + 1)], axis=1)
    out[idx] = win.min(axis=1) >= floor
    return out


def laser_ratio_image(off: np.ndarray, on: np.ndarray, *, floor: float = 40.0) -> np.ndarray:
    """The laser profile with the target's albedo divided out: ``on / off`` scaled to
    about 0-255 (0 where the laser-off image is darker than ``floor``)."""
    offf = off.astype(np.float64)
    r = np.where(offf >= floor, on.astype(np.float64) / np.maximum(offf, 1.0), 0.0)
    top = np.percentile(r[r > 0], 99.9) if np.any(r > 0) else 1.0
    return np.clip(r * (230.0 / max(top, 1e-9)), 0, 254.0)


def calibrate_laser_plane(camera: Camera, pairs, target, *,
                          stripe: StripeOptions | None = None,
                          names: list[str] | None = None,
                          min_points: int = 30) -> LaserPlaneCalibration:
    """Fit the sheet's plane from ``pairs`` of (laser-off, laser-on) images of a target.

    Parameters
    ----------
    camera : Camera
        Calibrated intrinsics (``cam_from_world`` ignored: results in the camera frame).
    pairs : sequence of (off (h, w) uint8, on (h, w) uint8)
    target : ChArUcoTarget or ChessboardTarget
    stripe : StripeOptions, optional
    names : list of str, optional
        Names of the poses for messages.

    Raises
    ------
    RuntimeError
        Fewer than two poses with both the board and enough stripe points.
    """
    # the ratio image has no ambient left, but the target's dark squares (zeroed below
    # ``floor``) cut the stripe into cliffs: the profile-steepness test would reject the
    # sound peaks next to them, so it is off here
    opt = dataclasses.replace(stripe or StripeOptions(), max_steepness=0.0)
    names = names or [f"pose {i}" for i in range(len(pairs))]
    cam = camera.with_pose(np.eye(4))
    pts_all, used, rejected, obs = [], [], [], []
    w_b, h_b = target.size_m()
    for i, (off, on) in enumerate(pairs):
        det = detect_board(target, off)
        if det is None or len(det[0]) < 8:
            rejected.append(i)
            log.warning("laser-plane calibration: target not detected in %s", names[i])
            continue
        cols, _ = detect_peaks(laser_ratio_image(off, on), options=opt)
        rows = np.flatnonzero(np.isfinite(cols))
        cols = cols[rows]
        keep = _bright_around(off, rows, cols)
        rows, cols = rows[keep], cols[keep]
        if len(rows) < min_points // 2:
            rejected.append(i)
            log.warning("laser-plane calibration: no stripe on the target in %s", names[i])
            continue
        spx = np.stack([cols, rows.astype(float)], 1)
        P, sel = _sheet_points(cam, det[0], det[1], spx, (w_b, h_b))
        if len(P) < min_points // 2:
            rejected.append(i)
            continue
        pts_all.append(P)
        obs.append((det[0], det[1], spx[sel]))
        used.append(i)
    if len(used) < 2:
        raise RuntimeError(f"laser-plane calibration: the stripe and the target were found in "
                           f"{len(used)} poses, need 2 (failed: "
                           f"{', '.join(names[i] for i in rejected)})")
    plane, inl = _robust_plane(np.concatenate(pts_all))
    P = np.concatenate(pts_all)
    rms = float(np.sqrt(np.mean((P[inl] @ plane[:3] - plane[3]) ** 2)))
    per_view = [float(np.sqrt(np.mean((Q @ plane[:3] - plane[3]) ** 2))) for Q in pts_all]
    jack = []
    if len(pts_all) >= 3:
        for i in range(len(pts_all)):
            pl, _ = _robust_plane(np.concatenate(pts_all[:i] + pts_all[i + 1:]))
            jack.append(pl)
    return LaserPlaneCalibration(plane, rms, int(inl.sum()), used, rejected, per_view,
                                 np.asarray(jack).reshape(-1, 4), obs, (w_b, h_b))


def _sheet_points(cam: Camera, obj: np.ndarray, px: np.ndarray, stripe_px: np.ndarray,
                  board_size) -> tuple[np.ndarray, np.ndarray]:
    """Stripe pixels ``(m, 2)`` lifted onto the board posed by PnP: the 3-D sheet points
    on the board ``(k, 3)`` and the mask ``(m,)`` of the pixels that gave them."""
    T = board_pose(obj, px, cam)
    n_b = T[:3, 2]
    plane_b = np.append(n_b, n_b @ T[:3, 3])
    P = intersect_rays_plane(pixel_rays(cam, stripe_px), plane_b)
    # keep points on the board (target frame: 0..w, 0..h)
    q = (P - T[:3, 3]) @ T[:3, :3]
    sel = ((q[:, 0] > 0) & (q[:, 0] < board_size[0]) & (q[:, 1] > 0)
           & (q[:, 1] < board_size[1]) & np.all(np.isfinite(P), axis=1))
    return P[sel], sel


def refit_laser_plane(camera: Camera, cal: LaserPlaneCalibration) -> np.ndarray:
    """The laser plane ``(4,)`` refitted from ``cal``'s observations (the same board
    corners and stripe pixels) under another ``camera``'s intrinsics: how an intrinsics
    error carries into the plane (board poses and stripe rays both move)."""
    if not cal.observations:
        raise ValueError("cal: expected a calibration that kept its observations "
                         "(from calibrate_laser_plane)")
    cam = camera.with_pose(np.eye(4))
    P = np.concatenate([_sheet_points(cam, o, p, s, cal.board_size)[0]
                        for o, p, s in cal.observations])
    return _robust_plane(P)[0]


def _robust_plane(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Plane ``(4,)`` (d >= 0) fitted with 3-sigma (MAD) rejection, and the inlier mask."""
    inl = np.ones(len(P), bool)
    for _ in range(3):
        n, d = fit_plane(P[inl])
        r = P @ n - d
        s = 1.4826 * np.median(np.abs(r[inl])) + 1e-9
        inl = np.abs(r) < 3 * s
    n, d = fit_plane(P[inl])
    if d < 0:
        n, d = -n, -d
    return np.append(n, d), inl


@dataclass
class AxisCalibration:
    """The turntable axis (or stage direction) in the camera frame.

    Attributes
    ----------
    direction : (3,) float64   unit; a positive reading turns right-handed about it (or
                               moves the object along it, for a stage)
    point : (3,) float64       a point of the axis (the one nearest the board's centre);
                               zeros for a stage
    rms_px : float             RMS reprojection of the corners under the fitted motion
    used_views, rejected_views : list of int
    scale : float              stage only: the fitted metres per stage metre (1 = exact)
    """

    direction: np.ndarray
    point: np.ndarray
    rms_px: float
    used_views: list
    rejected_views: list
    scale: float = 1.0

    def to_dict(self) -> dict:
        return {"direction": self.direction.tolist(), "point": self.point.tolist(),
                "rms_px": self.rms_px, "used_views": self.used_views,
                "rejected_views": self.rejected_views, "scale": self.scale}


def _poses(camera, images, target, names):
    cam = camera.with_pose(np.eye(4))
    obs, poses, used, rejected = [], [], [], []
    for i, img in enumerate(images):
        det = detect_board(target, img)
        if det is None or len(det[0]) < 8:
            rejected.append(i)
            log.warning("axis calibration: target not detected in %s", names[i])
            continue
        poses.append(board_pose(det[0], det[1], cam))
        obs.append(det[:2])
        used.append(i)
    return cam, obs, poses, used, rejected


def calibrate_turntable_axis(camera: Camera, images, angles_deg, target, *,
                             names: list[str] | None = None) -> AxisCalibration:
    """Fit the turntable axis from target images at known turntable readings (degrees)."""
    import cv2
    from scipy.optimize import least_squares

    names = names or [f"view {i}" for i in range(len(images))]
    ang = np.radians(np.asarray(angles_deg, float))
    if len(ang) != len(images):
        raise ValueError(f"angles_deg: expected {len(images)} readings, got {len(ang)}")
    cam, obs, poses, used, rejected = _poses(camera, images, target, names)
    if len(used) < 3:
        raise RuntimeError(f"axis calibration: target found in {len(used)} views, need 3")
    ang = ang[used]
    R0, t0 = poses[0][:3, :3], poses[0][:3, 3]
    # linear start, then the reprojection errors of every view
    centre0 = poses[0][:3, :3] @ np.r_[np.asarray(target.size_m()) / 2, 0] + t0
    axis, c = fit_axis([T[:3, :3] for T in poses], [T[:3, 3] for T in poses], ang,
                       near=centre0)

    def unpack(x):
        a = x[:3] / np.linalg.norm(x[:3])
        T0 = np.eye(4)
        T0[:3, :3] = cv2.Rodrigues(x[6:9])[0]
        T0[:3, 3] = x[9:12]
        return a, x[3:6], T0

    def resid(x):
        a, p, T0 = unpack(x)
        out = []
        for (objp, px), phi in zip(obs, ang, strict=True):
            T = rotation_about(a, phi - ang[0], p) @ T0
            q = transform_points(T, objp)
            proj = cam.project(q)[0]
            out.append((proj - px).ravel())
        out.append([1e3 * ((p - centre0) @ a), 1e3 * (np.linalg.norm(x[:3]) - 1)])  # gauges
        return np.concatenate(out)

    x0 = np.concatenate([axis, c, cv2.Rodrigues(R0)[0].ravel(), t0])
    sol = least_squares(resid, x0, method="lm", x_scale="jac")
    a, p, _ = unpack(sol.x)
    r = resid(sol.x)[:-2]
    return AxisCalibration(a, p, float(np.sqrt(np.mean(r.reshape(-1, 2) ** 2) * 2)), used,
                           rejected)


def calibrate_stage(camera: Camera, images, positions_m, target, *,
                    names: list[str] | None = None) -> AxisCalibration:
    """Fit the linear stage's direction from target images at known stage readings (m)."""
    names = names or [f"view {i}" for i in range(len(images))]
    pos = np.asarray(positions_m, float)
    if len(pos) != len(images):
        raise ValueError(f"positions_m: expected {len(images)} readings, got {len(pos)}")
    cam, obs, poses, used, rejected = _poses(camera, images, target, names)
    if len(used) < 2:
        raise RuntimeError(f"stage calibration: target found in {len(used)} views, need 2")
    pos = pos[used]
    t = np.stack([T[:3, 3] for T in poses])
    X = np.column_stack([np.ones(len(pos)), pos])
    coef = np.linalg.lstsq(X, t, rcond=None)[0]
    v = coef[1]
    scale = float(np.linalg.norm(v))
    pred = coef[0] + pos[:, None] * v
    err = []
    for (objp, px), T, tp in zip(obs, poses, pred, strict=True):
        q = objp @ T[:3, :3].T + tp
        err.append(cam.project(q)[0] - px)
    rms = float(np.sqrt(np.mean(np.concatenate(err) ** 2) * 2))
    return AxisCalibration(v / scale, np.zeros(3), rms, used, rejected, scale)
