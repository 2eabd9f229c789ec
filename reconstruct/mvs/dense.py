"""Dense depth on the CPU for posed views: rectified pairs with SGBM, then a
geometric consistency filter.

COLMAP's PatchMatch stereo needs CUDA, so the dense surface of the SfM pipeline is
built here:

1. :func:`select_neighbors`: for each reference view, the views that share the
   most sparse points at a useful triangulation angle (COLMAP's view selection idea).
2. :func:`pair_depth`: rectify the reference and one neighbour
   (``cv2.stereoRectify``), run semi-global block matching (``cv2.StereoSGBM``) in a
   disparity range taken from the sparse points, turn disparity into 3-D points in
   the rectified frame and resample them (nearest neighbour, never blending across
   an edge) back onto the reference's own pixels as z-depth.
3. :func:`consistency_filter`: keep a depth only when at least ``min_views`` other
   depth maps agree with it within a relative tolerance after reprojection.

Fusion into a surface is :func:`reconstruct.surface.tsdf.fuse_depth_maps` (shared with the
stereo and structured-light pipelines).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from acquire.camera import Camera
from core.config import Config, option
from core.progress import track
from core.validate import check_positive

__all__ = ["DenseOptions", "select_neighbors", "pair_depth", "consistency_filter",
           "depth_maps"]

log = logging.getLogger(__name__)


@dataclass
class DenseOptions(Config):
    """Options of the dense stage (rectified-pair SGBM depth maps, consistency filter)."""

    num_neighbors: int = option(4, range="[1, 64]",
                                help="views checked against each depth map by the "
                                     "consistency filter")
    min_angle_deg: float = option(5.0, unit="deg", range="[0, 90]",
                                  help="smallest useful triangulation angle with a partner")
    max_angle_deg: float = option(40.0, unit="deg", range="(0, 90]",
                                  help="largest useful triangulation angle with a partner")
    block_size: int = option(5, unit="px", range="[1, 31]", help="SGBM matching window (odd)")
    uniqueness: int = option(10, unit="%", range="[0, 100]", help="SGBM uniqueness ratio")
    depth_margin: float = option(0.25, range="[0, 10]",
                                 help="a view's depth range: its sparse points' widened by "
                                      "this fraction")
    consistency_tol: float = option(0.01, range="(0, 1)",
                                    help="relative depth agreement the consistency filter "
                                         "requires")
    min_views: int = option(1, range="[0, 64]",
                            help="other depth maps that must agree for a depth to survive")
    min_gradient: float = option(2.0, unit="8-bit", range="[0, inf)",
                                 help="pixels whose 7x7 grey-level standard deviation is "
                                      "below this (flat or black background) get no depth")


def _centre(cam: Camera) -> np.ndarray:
    return cam.center


def select_neighbors(cameras: Sequence[Camera], visible: Sequence[np.ndarray],
                     points: np.ndarray, *, k: int = 4, min_angle_deg: float = 5.0,
                     max_angle_deg: float = 40.0) -> list[list[int]]:
    """Rank the partners of each view by shared sparse points and angle.

    Parameters
    ----------
    cameras : sequence of Camera
    visible : sequence of (m_i,) int
        Indices into ``points`` of the sparse points each view observes.
    points : (n, 3) float64
        Sparse points.
    k : int
        Partners kept per view.

    Returns
    -------
    list of list of int
        ``k`` (or fewer) partners per view, best first. The score of a pair is the
        number of shared points whose triangulation angle lies in the useful range,
        weighted toward angles of about 15 degrees.
    """
    n = len(cameras)
    sets = [set(np.asarray(v).tolist()) for v in visible]
    centres = np.array([_centre(c) for c in cameras])
    lo, hi = np.radians(min_angle_deg), np.radians(max_angle_deg)
    out = []
    for i in range(n):
        scores = []
        for j in range(n):
            if j == i:
                continue
            shared = np.fromiter(sets[i] & sets[j], dtype=np.int64)
            if len(shared) < 5:
                continue
            p = points[shared]
            a = centres[i] - p
            b = centres[j] - p
            cosang = np.sum(a * b, 1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
            ang = np.arccos(np.clip(cosang, -1, 1))
            good = (ang > lo) & (ang < hi)
            med = np.median(ang)
            w = np.exp(-0.5 * ((med - np.radians(15.0)) / np.radians(10.0)) ** 2)
            scores.append((good.sum() * w, j))
        scores.sort(reverse=True)
        out.append([j for s, j in scores[:k] if s > 0])
    return out


def _texture_mask(gray: np.ndarray, min_std: float) -> np.ndarray:
    g = gray.astype(np.float32)
    m = cv2.blur(g, (7, 7))
    v = cv2.blur(g * g, (7, 7)) - m * m
    return np.sqrt(np.maximum(v, 0)) >= min_std


def _rectified_projection(cam_ref: Camera, R1: np.ndarray):
    """Our own rectified projection: the reference's focal length, and an image that holds
    the whole reference view (stereoRectify's alpha zooms badly for converging views).
    Returns ``(f, P (3, 4), (width, height))``."""
    f = 0.5 * (cam_ref.fx + cam_ref.fy)
    W, H = cam_ref.width, cam_ref.height
    corners = np.array([[0, 0], [W - 1, 0], [0, H - 1], [W - 1, H - 1], [W / 2, 0],
                        [W / 2, H - 1], [0, H / 2], [W - 1, H / 2]], np.float64)[:, None]
    rc = cv2.undistortPoints(corners, cam_ref.K, cam_ref.dist, R=R1).reshape(-1, 2) * f
    lo, hi = rc.min(0), rc.max(0)
    rw = int(min(np.ceil(hi[0] - lo[0]) + 1, 2 * W))
    rh = int(min(np.ceil(hi[1] - lo[1]) + 1, 2 * H))
    cx = -lo[0] if rw < 2 * W else rw / 2.0
    cy = -lo[1] if rh < 2 * H else rh / 2.0
    return f, np.array([[f, 0, cx, 0], [0, f, cy, 0], [0, 0, 1, 0]], np.float64), (rw, rh)


def _reference_depth(disp: np.ndarray, valid: np.ndarray, baseline: float, cam_ref: Camera,
                     R1: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Rectified disparities -> z-depth in the reference camera's own pixels (0: none)."""
    f, cx, cy = P[0, 0], P[0, 2], P[1, 2]
    rh, rw = disp.shape
    # rectified 3-D points; flipping keeps the disparity's magnitude because both
    # rectified views share the principal point
    Z = np.where(valid, f * baseline / np.where(valid, disp, 1.0), 0.0)
    u, v = np.meshgrid(np.arange(rw, dtype=np.float64), np.arange(rh, dtype=np.float64))
    X = (u - cx) * Z / f
    Y = (v - cy) * Z / f
    # z in the reference camera frame: p_ref = R1^T p_rect
    zref = (R1[0, 2] * X + R1[1, 2] * Y + R1[2, 2] * Z).astype(np.float32)
    zref[~valid] = 0.0
    # back to the reference's own pixels: rectified coordinates of every original pixel
    W, H = cam_ref.width, cam_ref.height
    uo, vo = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    px = np.stack([uo.ravel(), vo.ravel()], 1)[:, None, :]
    rect = cv2.undistortPoints(px, cam_ref.K, cam_ref.dist, R=R1, P=P[:, :3]).reshape(H, W, 2)
    return cv2.remap(zref, rect[..., 0].astype(np.float32), rect[..., 1].astype(np.float32),
                     cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def pair_depth(gray_ref: np.ndarray, gray_src: np.ndarray, cam_ref: Camera, cam_src: Camera,
               depth_range: tuple[float, float], *, block_size: int = 5,
               uniqueness: int = 10, min_gradient: float = 2.0) -> np.ndarray:
    """Z-depth of the reference view from one rectified pair and SGBM.

    Parameters
    ----------
    gray_ref, gray_src : (H, W) uint8
        Grey images of the two views (their own sizes).
    cam_ref, cam_src : Camera
        Posed, calibrated cameras (OpenCV convention, distortion allowed).
    depth_range : (float, float)
        Expected z-depths in the reference view; sets the disparity search range.
    block_size, uniqueness : int
        SGBM window and uniqueness ratio (percent).
    min_gradient : float
        Reference pixels whose 7x7 grey-level standard deviation is lower get no
        depth (flat regions and black background match anything).

    Returns
    -------
    (H, W) float32
        Z-depth in the reference camera frame (world units), 0 where unknown.
    """
    zmin, zmax = (check_positive(depth_range[0], "depth_range[0]"),
                  check_positive(depth_range[1], "depth_range[1]"))
    size = (cam_ref.width, cam_ref.height)
    if (cam_src.width, cam_src.height) != size:
        raise ValueError("cam_src: expected the size of cam_ref for a stereo pair")
    T = cam_src.cam_from_world @ cam_ref.world_from_cam  # src_from_ref
    R, t = T[:3, :3], T[:3, 3]
    # is the source to the right (x > 0) of the reference? SGBM wants the reference left
    src_in_ref = -R.T @ t
    R1, R2, _, _, _, _, _ = cv2.stereoRectify(cam_ref.K, cam_ref.dist, cam_src.K, cam_src.dist,
                                              size, R, t, flags=cv2.CALIB_ZERO_DISPARITY)
    f, P, (rw, rh) = _rectified_projection(cam_ref, R1)
    src_rect = R1 @ src_in_ref
    baseline = abs(src_rect[0])
    flip = src_rect[0] < 0
    rsize = (rw, rh)
    # rectified z differs from the reference's z by the rectifying rotation: widen
    dmin = f * baseline / (zmax * 1.15)
    dmax = f * baseline / (zmin * 0.85)
    # the source is rectified shifted right by the smallest expected disparity, so that
    # its content is not cut off and SGBM searches [0, num)
    shift = max(int(np.floor(dmin)), 0)
    P2 = P.copy()
    P2[0, 2] += -shift if flip else shift
    m1 = cv2.initUndistortRectifyMap(cam_ref.K, cam_ref.dist, R1, P[:, :3], rsize, cv2.CV_32FC1)
    m2 = cv2.initUndistortRectifyMap(cam_src.K, cam_src.dist, R2, P2[:, :3], rsize, cv2.CV_32FC1)
    left = cv2.remap(gray_ref, m1[0], m1[1], cv2.INTER_LINEAR)
    right = cv2.remap(gray_src, m2[0], m2[1], cv2.INTER_LINEAR)
    if flip:
        left, right = left[:, ::-1].copy(), right[:, ::-1].copy()
    min_disp = int(np.floor(dmin)) - shift
    num = int(np.ceil((dmax - shift - min_disp) / 16.0)) * 16
    num = max(16, min(num, 16 * ((2 * rw) // 16)))
    bs = int(block_size)
    sgbm = cv2.StereoSGBM_create(minDisparity=min_disp, numDisparities=num, blockSize=bs,
                                 P1=8 * bs * bs, P2=32 * bs * bs, disp12MaxDiff=1,
                                 uniquenessRatio=int(uniqueness), speckleWindowSize=100,
                                 speckleRange=2, mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
    log.debug("pair: f=%.1f B=%.4f disparities %d + [%d, %d) flip=%s", f, baseline, shift,
              min_disp, min_disp + num, flip)
    # SGBM leaves a left border of min_disp + num columns invalid: pad it away
    pad = max(min_disp, 0) + num
    padded = [np.concatenate([np.zeros((rh, pad), np.uint8), im], 1) for im in (left, right)]
    disp = sgbm.compute(*padded)[:, pad:].astype(np.float32) / 16.0
    valid = disp >= min_disp
    disp += shift
    valid &= disp > 0
    if flip:
        disp, valid = disp[:, ::-1], valid[:, ::-1]
    out = _reference_depth(disp, valid, baseline, cam_ref, R1, P)
    out[(out < zmin * 0.8) | (out > zmax * 1.2)] = 0.0
    out[~_texture_mask(gray_ref, min_gradient)] = 0.0
    return out


def consistency_filter(depths: Sequence[np.ndarray], cameras: Sequence[Camera],
                       neighbors: Sequence[Sequence[int]], *, tol: float = 0.01,
                       min_views: int = 1) -> list[np.ndarray]:
    """Keep depths that other views' depth maps confirm.

    Each pixel's 3-D point is projected into the neighbouring views; it counts as
    confirmed by a view when that view's depth at the projected pixel (nearest) is
    within ``tol`` (relative) of the point's depth in that view.

    Parameters
    ----------
    depths : sequence of (H, W) float32
    cameras : sequence of Camera
    neighbors : sequence of sequence of int
        The views to check each depth map against.

    Returns
    -------
    list of (H, W) float32
        Filtered copies (0 = removed).
    """
    out = []
    for i in range(len(depths)):
        d = depths[i]
        cam = cameras[i]
        vv, uu = np.nonzero(d > 0)
        if len(vv) == 0:
            out.append(d.copy())
            continue
        pts = cam.unproject(np.stack([uu, vv], 1).astype(np.float64), d[vv, uu].astype(np.float64))
        count = np.zeros(len(pts), np.int32)
        for j in neighbors[i]:
            cj, dj = cameras[j], depths[j]
            px, z = cj.project(pts)
            ui = np.round(px[:, 0]).astype(np.int64)
            vi = np.round(px[:, 1]).astype(np.int64)
            inside = (z > 0) & (ui >= 0) & (vi >= 0) & (ui < cj.width) & (vi < cj.height)
            dz = np.zeros(len(pts))
            dz[inside] = dj[vi[inside], ui[inside]]
            ok = inside & (dz > 0) & (np.abs(dz - z) <= tol * z)
            count += ok
        keep = count >= min_views
        f = np.zeros_like(d)
        f[vv[keep], uu[keep]] = d[vv[keep], uu[keep]]
        out.append(f)
    return out


def depth_maps(grays: Sequence[np.ndarray], cameras: Sequence[Camera],
               visible: Sequence[np.ndarray], points: np.ndarray, *,
               options: DenseOptions | None = None) -> tuple[list[np.ndarray], list[list[int]]]:
    """Filtered depth maps of every view (see the module docstring).

    Parameters
    ----------
    grays : sequence of (H, W) uint8
    cameras : sequence of Camera
        Posed cameras of the registered views.
    visible : sequence of (m_i,) int
        Sparse points seen by each view (indices into ``points``).
    points : (n, 3) float64
        Sparse points in the cameras' world frame.

    Returns
    -------
    depths : list of (H, W) float32
        Z-depth per view after the consistency filter (0 = none).
    neighbors : list of list of int
        The partners chosen per view (the first one was the stereo partner).
    """
    opt = options or DenseOptions()
    neighbors = select_neighbors(cameras, visible, points, k=max(opt.num_neighbors, 1),
                                 min_angle_deg=opt.min_angle_deg, max_angle_deg=opt.max_angle_deg)
    # a rectified pair needs two images of one size (portrait and landscape photos differ)
    neighbors = [[j for j in nb if (cameras[j].width, cameras[j].height)
                  == (cameras[i].width, cameras[i].height)] for i, nb in enumerate(neighbors)]
    raw = []
    for i in track(range(len(cameras)), "dense depth (SGBM)", total=len(cameras)):
        cam = cameras[i]
        vis = np.asarray(visible[i], np.int64)
        if not neighbors[i] or len(vis) < 5:
            raw.append(np.zeros((cam.height, cam.width), np.float32))
            continue
        z = cam.to_camera(points[vis])[:, 2]
        z = z[z > 0]
        lo, hi = np.percentile(z, [1, 99]) if len(z) else (0.0, 0.0)
        if not hi > 0:
            raw.append(np.zeros((cam.height, cam.width), np.float32))
            continue
        m = opt.depth_margin
        rng_ = (max(lo * (1 - m), 1e-6), hi * (1 + m))
        j = neighbors[i][0]
        d = pair_depth(grays[i], grays[j], cam, cameras[j], rng_, block_size=opt.block_size,
                       uniqueness=opt.uniqueness, min_gradient=opt.min_gradient)
        raw.append(d)
    filtered = consistency_filter(raw, cameras, neighbors, tol=opt.consistency_tol,
                                  min_views=opt.min_views)
    return filtered, neighbors
