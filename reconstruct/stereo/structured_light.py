"""Structured light: decode Gray code + phase shift, triangulate with the projector.

The projector is an inverse camera. Gray code gives each camera pixel the integer
projector column (and row) it sees; N-step phase shifting gives the column modulo
the sinusoid period with sub-pixel precision; the two combine into an absolute
sub-pixel projector coordinate. A camera ray meets the projector's plane of that
column (through the projector centre) at the surface point.

Pattern order follows :mod:`acquire.stereo.patterns`: Gray-code images (pattern, inverse
per bit, most significant first; columns then rows), then the phase-shift images.

References
----------
Moreno, D. and Taubin, G. (2012), "Simple, accurate, and robust projector-camera
calibration", 3DIMPVT. doi:10.1109/3DIMPVT.2012.77
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from acquire.camera import Camera
from core.frames import transform_points

__all__ = ["decode_gray_code", "decode_phase", "unwrap_with_gray", "triangulate_columns",
           "projector_coords_at", "gray_bit_errors"]


def _stack(images, name):
    arr = np.stack([np.asarray(i, dtype=np.float64) for i in images])
    if arr.ndim != 3:
        raise ValueError(f"{name}: expected a list of (H, W) grayscale images, got shape "
                         f"{arr.shape[1:]}")
    return arr


def decode_gray_code(images: Sequence[np.ndarray], *, n_col_bits: int, n_row_bits: int,
                     white: np.ndarray | None = None, black: np.ndarray | None = None,
                     min_contrast: float = 0.02, min_bit_contrast: float = 0.005
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Projector column and row per camera pixel from Gray-code captures.

    Parameters
    ----------
    images : sequence of (H, W) float
        ``2 * (n_col_bits + n_row_bits)`` captures: pattern then inverse per bit.
    n_col_bits, n_row_bits : int
        See :func:`acquire.stereo.patterns.gray_code_bits`.
    white, black : (H, W) float, optional
        Captures under full and no projector light; pixels with
        ``white - black < min_contrast`` are in the projector's shadow.
    min_contrast, min_bit_contrast : float
        In image units (scale of ``images``).

    Returns
    -------
    col, row : (H, W) int64
        Projector column and row (-1 where invalid).
    valid : (H, W) bool
    """
    n_bits = int(n_col_bits) + int(n_row_bits)
    if len(images) != 2 * n_bits:
        raise ValueError(f"images: expected {2 * n_bits} Gray-code captures "
                         f"(pattern and inverse for {n_bits} bits), got {len(images)}")
    arr = _stack(images, "images")
    pos, neg = arr[0::2], arr[1::2]
    bits = pos > neg
    valid = np.all(np.abs(pos - neg) > min_bit_contrast, axis=0)
    if white is not None and black is not None:
        valid &= (np.asarray(white, float) - np.asarray(black, float)) > min_contrast

    def gray_to_int(b):
        out = np.zeros(b.shape[1:], np.int64)
        acc = np.zeros(b.shape[1:], bool)
        for k in range(len(b)):  # binary_k = binary_{k-1} xor gray_k, MSB first
            acc = acc ^ b[k]
            out = (out << 1) | acc
        return out

    col = gray_to_int(bits[:n_col_bits])
    row = gray_to_int(bits[n_col_bits:])
    col = np.where(valid, col, -1)
    row = np.where(valid, row, -1)
    return col, row, valid


def gray_bit_errors(images: Sequence[np.ndarray], true_col: np.ndarray, *, n_bits: int,
                    mask: np.ndarray | None = None) -> np.ndarray:
    """Error rate of each column bit's decision (pattern brighter than its inverse)
    against the true projector column ``true_col (H, W)`` (negative: unknown), counted
    off the bit's transitions: pixels whose neighbouring projector columns (+-1) carry
    the same bit, so a pixel straddling a stripe edge is not an error. ``images``: the
    ``2 n_bits`` column captures (pattern, inverse per bit, MSB first). Returns
    ``(n_bits,)`` (NaN for a bit that changes every column)."""
    arr = _stack(images, "images")[: 2 * n_bits]
    bits = arr[0::2] > arr[1::2]
    c = np.asarray(true_col, np.int64)
    ok = c >= 0 if mask is None else (c >= 0) & np.asarray(mask, bool)
    out = np.full(n_bits, np.nan)
    gray = [(x ^ (x >> 1)) for x in (c, np.maximum(c - 1, 0), c + 1)]
    for k in range(n_bits):
        b = [(g >> (n_bits - 1 - k)) & 1 for g in gray]
        stable = ok & (b[0] == b[1]) & (b[0] == b[2]) & (c >= 1)
        if stable.any():
            out[k] = float(np.mean(bits[k][stable] != b[0][stable].astype(bool)))
    return out


def decode_phase(images: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Wrapped phase and modulation from N-step phase-shift captures.

    For ``I_k = A + B cos(phi - 2 pi k / N)``:
    ``phi = atan2(sum I_k sin(2 pi k / N), sum I_k cos(2 pi k / N))``.

    Returns
    -------
    phase : (H, W) float64 in [0, 2 pi)
    modulation : (H, W) float64
        ``B`` (the sinusoid's amplitude in image units).
    """
    arr = _stack(images, "images")
    n = len(arr)
    if n < 3:
        raise ValueError(f"images: expected at least 3 phase-shift captures, got {n}")
    k = 2 * np.pi * np.arange(n) / n
    s = np.tensordot(np.sin(k), arr, axes=1)
    c = np.tensordot(np.cos(k), arr, axes=1)
    phase = np.mod(np.arctan2(s, c), 2 * np.pi)
    return phase, 2.0 / n * np.hypot(s, c)


def unwrap_with_gray(phase: np.ndarray, gray: np.ndarray, *, period_px: float) -> np.ndarray:
    """Absolute sub-pixel projector coordinate from wrapped phase and Gray-code integer.

    ``c = phase * P / (2 pi) + P * round((gray - phase * P / (2 pi)) / P)``: the
    Gray code only has to be right to within half a period.
    """
    cw = phase * period_px / (2 * np.pi)
    out = cw + period_px * np.round((gray - cw) / period_px)
    return np.where(gray >= 0, out, np.nan)


def triangulate_columns(camera: Camera, pixels: np.ndarray, proj_xy: np.ndarray,
                        projector: Camera) -> np.ndarray:
    """Intersect camera rays with the projector's column planes.

    Parameters
    ----------
    camera : Camera
        Calibrated camera (``cam_from_world`` = world frame of the result).
    pixels : (n, 2) float64
        Camera pixels.
    proj_xy : (n, 2) float64
        Projector (column, row) seen at each pixel; the row only serves to undistort.
    projector : Camera
        The calibrated projector (inverse camera), pose in the same world frame.

    Returns
    -------
    (n, 3) float64 world points (NaN where the ray is parallel to the plane or the
    point is behind either device).
    """
    o, d = camera.rays(pixels)
    xn = projector.normalized(proj_xy)[:, 0]
    R = projector.cam_from_world[:3, :3]
    op = transform_points(projector.cam_from_world, o)
    dp = d @ R.T
    den = dp[:, 0] - xn * dp[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        tt = (xn * op[:, 2] - op[:, 0]) / den
    bad = ~np.isfinite(tt) | (tt <= 0) | (np.abs(den) < 1e-9)
    pts = o + tt[:, None] * d
    zp = transform_points(projector.cam_from_world, pts)[:, 2]
    bad |= zp <= 0
    pts[bad] = np.nan
    return pts


def projector_coords_at(points_px: np.ndarray, proj_col: np.ndarray, proj_row: np.ndarray,
                        valid: np.ndarray, *, window: int = 15, min_valid: int = 30
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Projector coordinates at sub-pixel camera points by local homographies.

    For each camera point (a board corner), fit a homography from the decoded
    camera pixels in a ``window`` x ``window`` neighbourhood to their projector
    coordinates and apply it at the point (Moreno and Taubin 2012).

    Parameters
    ----------
    points_px : (k, 2) float64
    proj_col, proj_row : (H, W) float64
        Decoded sub-pixel projector coordinates (NaN where invalid).
    valid : (H, W) bool

    Returns
    -------
    proj_px : (k, 2) float64
    ok : (k,) bool
    """
    import cv2

    H, W = proj_col.shape
    half = window // 2
    out = np.full((len(points_px), 2), np.nan)
    ok = np.zeros(len(points_px), bool)
    good = valid & np.isfinite(proj_col) & np.isfinite(proj_row)
    for i, (x, y) in enumerate(np.asarray(points_px, float)):
        xi, yi = int(round(x)), int(round(y))
        x0, x1 = max(xi - half, 0), min(xi + half + 1, W)
        y0, y1 = max(yi - half, 0), min(yi + half + 1, H)
        if x1 <= x0 or y1 <= y0:
            continue
        g = good[y0:y1, x0:x1]
        if g.sum() < min_valid:
            continue
        vv, uu = np.nonzero(g)
        src = np.stack([uu + x0, vv + y0], 1).astype(np.float64)
        dst = np.stack([proj_col[y0:y1, x0:x1][g], proj_row[y0:y1, x0:x1][g]], 1)
        Hm, _ = cv2.findHomography(src, dst, cv2.RANSAC, 1.0)
        if Hm is None:
            continue
        p = Hm @ np.array([x, y, 1.0])
        out[i] = p[:2] / p[2]
        ok[i] = True
    return out, ok
