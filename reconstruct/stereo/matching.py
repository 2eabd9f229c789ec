"""Passive and active stereo: dense matching on a rectified pair, disparity to points.

The pair is rectified by :mod:`reconstruct.calibration.rectify`. Disparity is
``x_left - x_right`` in rectified pixels, float32, NaN where invalid; depth maps are
z-depth in the rectified left camera.

>>> import numpy as np
>>> from reconstruct.calibration.rectify import StereoCalibration, rectify
>>> calib = StereoCalibration(np.array([[100., 0, 31.5], [0, 100, 23.5], [0, 0, 1]]), np.zeros(5),
...     np.array([[100., 0, 31.5], [0, 100, 23.5], [0, 0, 1]]), np.zeros(5), np.eye(3),
...     np.array([-0.1, 0, 0]), (64, 48))
>>> rect = rectify(calib)
>>> float(disparity_to_depth(np.full((48, 64), 10.0, np.float32), rect)[0, 0])
1.0
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np

from acquire.camera import Camera
from core.validate import check_choice, check_positive
from reconstruct.calibration.rectify import Rectification

__all__ = ["match", "MatchOptions", "disparity_to_depth", "depth_to_points", "lr_consistency",
           "disparity_range", "texture_mask"]

_log = logging.getLogger(__name__)


def disparity_range(rect: Rectification, z_min: float, z_max: float) -> tuple[int, int]:
    """``(min_disparity, num_disparities)`` for SGBM covering depths [z_min, z_max].

    ``num_disparities`` is rounded up to a multiple of 16 as SGBM requires.
    """
    z_min = check_positive(z_min, "z_min")
    z_max = check_positive(z_max, "z_max")
    fb = rect.focal * rect.baseline
    lo = int(np.floor(fb / z_max)) - 2
    hi = int(np.ceil(fb / z_min)) + 2
    lo = max(lo, 0)
    num = int(np.ceil((hi - lo) / 16.0)) * 16
    return lo, max(num, 16)


@dataclass
class MatchOptions:
    """Options of :func:`match`.

    Attributes
    ----------
    min_disparity, num_disparities : int
        Search range (``num_disparities`` a multiple of 16).
    block_size : int
        Odd matching window (3..11 typical).
    wls : bool
        Edge-aware weighted-least-squares filtering (ximgproc); densifies.
    wls_lambda, wls_sigma : float
    lr_check : bool
        Left-right consistency: drop pixels whose right-view disparity disagrees.
    lr_tol : float
        Pixels.
    uniqueness : int
        SGBM uniqueness ratio (percent).
    speckle_window, speckle_range : int
        SGBM speckle filter (0 window = off).
    mode : str
        "sgbm" (5 directions), "hh" (8 directions, full DP) or "3way".
    min_texture : float
        Drop disparities where the left image's local std (DN, block-size window) is
        below this (no signal to match: dark background, textureless surface); 0 = off.
    pad : bool
        Pad both images on the left (by ``num_disparities - min_disparity`` columns) so
        that SGBM also matches the left border it otherwise leaves empty (see
        :func:`match`).
    p1_scale, p2_scale : float
        SGBM smoothness penalties per channel and window pixel.
    roi_min_intensity : float
        Match only inside the bounding box (plus a margin) of the pixels whose 5 x 5
        mean exceeds this (DN): a dark background carries no signal to match, and the
        box around the lit object is typically half the image. 0 = the whole image.
    """

    min_disparity: int = 0
    num_disparities: int = 64
    block_size: int = 5
    wls: bool = False
    wls_lambda: float = 8000.0
    wls_sigma: float = 1.2
    lr_check: bool = False
    lr_tol: float = 1.0
    uniqueness: int = 5
    speckle_window: int = 100
    speckle_range: int = 2
    mode: str = "sgbm"
    pad: bool = True
    min_texture: float = 0.5
    p1_scale: float = 4.0
    p2_scale: float = 64.0
    roi_min_intensity: float = 8.0


def _sgbm(opts: MatchOptions, channels: int):
    import cv2

    mode = {"sgbm": cv2.StereoSGBM_MODE_SGBM, "hh": cv2.StereoSGBM_MODE_HH,
            "3way": cv2.StereoSGBM_MODE_SGBM_3WAY}[check_choice(opts.mode, "mode",
                                                                {"sgbm", "hh", "3way"})]
    if opts.num_disparities <= 0 or opts.num_disparities % 16:
        raise ValueError(f"num_disparities: expected a positive multiple of 16, got "
                         f"{opts.num_disparities}")
    if opts.block_size < 1 or opts.block_size % 2 == 0:
        raise ValueError(f"block_size: expected an odd integer >= 1, got {opts.block_size}")
    b2 = opts.block_size ** 2
    return cv2.StereoSGBM.create(
        minDisparity=int(opts.min_disparity), numDisparities=int(opts.num_disparities),
        blockSize=int(opts.block_size), P1=int(opts.p1_scale * channels * b2),
        P2=int(opts.p2_scale * channels * b2), disp12MaxDiff=-1,
        uniquenessRatio=int(opts.uniqueness), speckleWindowSize=int(opts.speckle_window),
        speckleRange=int(opts.speckle_range), preFilterCap=63, mode=mode)


def lr_consistency(disp_left: np.ndarray, disp_right: np.ndarray, *, tol: float = 1.0
                   ) -> np.ndarray:
    """``(H, W) bool``: left disparities confirmed by the right view.

    ``disp_right`` holds, at right pixel ``x_r``, the positive disparity to its left
    match (``x_l = x_r + d``). A left pixel ``x`` with disparity ``d`` is consistent when
    ``|disp_right[x - d] - d| <= tol``.
    """
    H, W = disp_left.shape
    xs = np.arange(W)[None, :] - np.nan_to_num(disp_left, nan=-1e9)
    xr = np.round(xs).astype(np.int64)
    inside = (xr >= 0) & (xr < W) & np.isfinite(disp_left)
    rows = np.broadcast_to(np.arange(H)[:, None], (H, W))
    dr = np.full((H, W), np.nan, np.float32)
    dr[inside] = disp_right[rows[inside], xr[inside]]
    return inside & np.isfinite(dr) & (np.abs(dr - disp_left) <= tol)


def match(left_rect: np.ndarray, right_rect: np.ndarray, options: MatchOptions | None = None
          ) -> np.ndarray:
    """Dense disparity of a rectified pair with StereoSGBM (+ WLS, + LR check).

    SGBM leaves the ``min_disparity + num_disparities`` leftmost columns unmatched. The
    right image is shifted right by ``min_disparity`` first (the search then starts at
    0, so only ``num_disparities`` columns are lost) and, with ``pad``, both images are
    padded on the left by ``num_disparities - min_disparity`` columns (when positive),
    so that every pixel with a possible match (``x >= min_disparity``) gets one. The
    right view's disparity (LR check, WLS) is the same matcher on the mirrored pair,
    whose unmatched border is the original right border.

    Parameters
    ----------
    left_rect, right_rect : (H, W) or (H, W, 3) uint8
    options : MatchOptions

    Returns
    -------
    (H, W) float32
        Disparity in pixels (1/16 sub-pixel from SGBM), NaN where invalid.
    """
    opts = options or MatchOptions()
    if left_rect.shape != right_rect.shape:
        raise ValueError(f"right_rect: expected the left image's shape {left_rect.shape}, "
                         f"got {right_rect.shape}")
    channels = 1 if left_rect.ndim == 2 else left_rect.shape[2]
    d = _match(left_rect, right_rect, opts, channels)
    if opts.min_texture > 0:
        d[~texture_mask(left_rect, opts.min_texture, opts.block_size)] = np.nan
    return d


def texture_mask(image: np.ndarray, min_std: float, window: int = 5) -> np.ndarray:
    """``(H, W) bool``: pixels whose ``window`` x ``window`` intensity std >= ``min_std``.

    Matching is meaningless where the image carries no signal (a dark background,
    a textureless surface); SGBM would otherwise smear disparities into it.
    """
    import cv2

    g = image.astype(np.float32)
    if g.ndim == 3:
        g = g.mean(axis=2)
    k = (max(int(window), 3) | 1,) * 2
    m = cv2.blur(g, k)
    v = cv2.blur(g * g, k) - m * m
    return np.sqrt(np.maximum(v, 0)) >= min_std


def _roi(image: np.ndarray, min_intensity: float, margin: int):
    """``(y0, y1, x0, x1)``: bounding box (plus ``margin``) of the pixels whose 5 x 5 mean
    exceeds ``min_intensity``; None when there is none."""
    import cv2

    g = image if image.ndim == 2 else image.mean(axis=2)
    m = cv2.blur(g.astype(np.float32), (5, 5)) > min_intensity
    rows = np.flatnonzero(m.any(axis=1))
    if len(rows) == 0:
        return None
    cols = np.flatnonzero(m.any(axis=0))
    H, W = m.shape
    return (max(rows[0] - margin, 0), min(rows[-1] + 1 + margin, H),
            max(cols[0] - margin, 0), min(cols[-1] + 1 + margin, W))


def _sgbm_raw(matcher, left, right, lo: int, num: int, pad: bool, roi_min: float = 0.0,
              margin: int = 8) -> np.ndarray:
    """SGBM's fixed-point disparity (x16, original units) of ``left`` against ``right``;
    ``(lo - 1) * 16`` where invalid. See :func:`match` for the shift, the padding and
    the region of interest."""
    H, W = left.shape[:2]
    out = np.full((H, W), (lo - 1) * 16, np.int32)
    y0, y1, x0, x1 = 0, H, 0, W
    if roi_min > 0:
        box = _roi(left, roi_min, margin)
        if box is None:
            return out
        y0, y1, x0, x1 = box
    # after the shift SGBM loses the columns x < num; those with x < lo have no match at
    # all (x - d < 0), so num - lo columns of padding recover every matchable pixel
    p = max(num - lo, 0) if pad else 0
    extra = ((0, 0),) if left.ndim == 3 else ()
    # right'[x] = right[x - lo]: the search starts at 0; in padded columns c = x + p
    rs = np.pad(right[y0:y1], ((0, 0), (lo + p, 0)) + extra, mode="edge")[:, :W + p]
    ls = np.pad(left[y0:y1], ((0, 0), (p, 0)) + extra, mode="edge") if p else left[y0:y1]
    ws = max(x0 + p - num, 0)  # SGBM needs num columns of context left of the first output
    we = x1 + p
    raw = matcher.compute(np.ascontiguousarray(ls[:, ws:we]), np.ascontiguousarray(rs[:, ws:we]))
    c0 = max(ws, p)  # first padded column that is an image column
    raw = raw[:, c0 - ws:]
    sub = raw.astype(np.int32) + 16 * lo
    sub[raw < 0] = (lo - 1) * 16
    out[y0:y1, c0 - p:c0 - p + sub.shape[1]] = sub
    return out


def _match(left_rect, right_rect, opts, channels):
    lo, num = int(opts.min_disparity), int(opts.num_disparities)
    if lo < 0:
        raise ValueError(f"min_disparity: expected >= 0, got {lo}")
    m = _sgbm(dataclasses.replace(opts, min_disparity=0), channels)
    roi = float(opts.roi_min_intensity)
    raw = _sgbm_raw(m, left_rect, right_rect, lo, num, opts.pad, roi, opts.block_size + 4)
    invalid_raw = (lo - 1) * 16
    if not (opts.wls or opts.lr_check):
        d = raw.astype(np.float32) / 16.0
        d[raw <= invalid_raw] = np.nan
        return d
    # right view: mirror both images; a right pixel's match lies to its right
    raw_r = _sgbm_raw(m, right_rect[:, ::-1], left_rect[:, ::-1], lo, num, opts.pad, roi,
                      opts.block_size + 4)[:, ::-1]
    dr = raw_r.astype(np.float32) / 16.0
    dr[raw_r <= invalid_raw] = np.nan
    if opts.wls:
        import cv2

        wls = cv2.ximgproc.createDisparityWLSFilterGeneric(True)
        wls.setDepthDiscontinuityRadius(max(int(np.ceil(0.33 * opts.block_size)), 1))
        wls.setLambda(float(opts.wls_lambda))
        wls.setSigmaColor(float(opts.wls_sigma))
        # ximgproc's convention: int16 x16, the right map negative, invalid below range
        left16 = np.where(raw <= invalid_raw, -16, raw).astype(np.int16)
        right16 = np.where(raw_r <= invalid_raw, 16, -raw_r).astype(np.int16)
        filt = wls.filter(left16, left_rect, disparity_map_right=right16,
                          right_view=right_rect)
        d = filt.astype(np.float32) / 16.0
        d[filt < lo * 16] = np.nan
    else:
        d = raw.astype(np.float32) / 16.0
        d[raw <= invalid_raw] = np.nan
    if opts.lr_check:
        base = raw.astype(np.float32) / 16.0
        base[raw <= invalid_raw] = np.nan
        ok = lr_consistency(base, dr, tol=opts.lr_tol)
        d[~ok] = np.nan
    return d


def disparity_to_depth(disparity: np.ndarray, rect: Rectification) -> np.ndarray:
    """Z-depth ``(H, W) float32`` in the rectified left camera (0 where invalid)."""
    d = np.asarray(disparity, np.float32)
    fb = rect.focal * rect.baseline
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(np.isfinite(d) & (d > 0), fb / d, 0.0)
    return z.astype(np.float32)


def depth_to_points(depth: np.ndarray, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """World points ``(n, 3)`` of the valid pixels of a z-depth map, and their ``(n, 2)`` pixels."""
    H, W = depth.shape
    if (H, W) != (camera.height, camera.width):
        raise ValueError(f"depth: expected shape ({camera.height}, {camera.width}), got {(H, W)}")
    v, u = np.nonzero(np.isfinite(depth) & (depth > 0))
    px = np.stack([u, v], 1).astype(np.float64)
    return camera.unproject(px, depth[v, u].astype(np.float64)), px
