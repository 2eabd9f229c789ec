"""Disparity error metrics with the Middlebury stereo benchmark's definitions.

``bad-t``: percentage of evaluated pixels whose absolute disparity error exceeds
``t`` pixels; ``avgerr``: mean absolute disparity error. Evaluated pixels are those
with a valid ground truth inside ``mask`` (typically the non-occluded pixels: seen
by both cameras). As in Middlebury v3, a pixel without an estimate is not dropped:
it counts as bad, and for ``avgerr`` its error is that of the nearest valid
estimate on its scanline (Middlebury fills holes by scanline interpolation); the
fraction of such pixels is reported as ``invalid``.

References
----------
Scharstein, D. et al. (2014), "High-resolution stereo datasets with subpixel-accurate
ground truth", GCPR. doi:10.1007/978-3-319-11752-2_3

>>> import numpy as np
>>> gt = np.full((1, 4), 10.0)
>>> est = np.array([[10.5, 11.5, 13.0, np.nan]])
>>> m = disparity_metrics(est, gt)
>>> m["bad1.0"], m["bad2.0"], m["avgerr"], m["invalid"]
(75.0, 50.0, 2.0, 25.0)
"""

from __future__ import annotations

import numpy as np

from core.validate import check_array

__all__ = ["disparity_metrics", "nonoccluded_mask"]


def _fill_scanlines(d: np.ndarray) -> np.ndarray:
    """Replace NaN by the nearest valid value on the same row (rows without any stay NaN)."""
    out = d.copy()
    H, W = d.shape
    idx = np.arange(W)
    for y in range(H):
        ok = np.isfinite(d[y])
        if ok.all() or not ok.any():
            continue
        good = idx[ok]
        pos = np.searchsorted(good, idx)
        left = good[np.clip(pos - 1, 0, len(good) - 1)]
        right = good[np.clip(pos, 0, len(good) - 1)]
        nearest = np.where(np.abs(idx - left) <= np.abs(right - idx), left, right)
        out[y, ~ok] = d[y, nearest[~ok]]
    return out


def disparity_metrics(disparity: np.ndarray, gt: np.ndarray, *, mask: np.ndarray | None = None,
                      thresholds=(1.0, 2.0)) -> dict:
    """Middlebury bad-t and avgerr.

    Parameters
    ----------
    disparity : (H, W) float
        Estimate; NaN (or non-finite) where the matcher gave none.
    gt : (H, W) float
        Ground truth; NaN, infinite or <= 0 where unknown.
    mask : (H, W) bool, optional
        Pixels to evaluate (e.g. :func:`nonoccluded_mask`).
    thresholds : sequence of float

    Returns
    -------
    dict
        ``"bad1.0"``, ``"bad2.0"`` (percent, dense: a missing estimate is bad),
        ``"avgerr"`` (pixels), ``"invalid"`` (percent of evaluated pixels without an
        estimate) and ``"density"`` (100 - invalid), ``"bad1.0_sparse"``,
        ``"bad2.0_sparse"`` (percent of the estimated pixels only, for reference),
        ``"n_pixels"``.

    Raises
    ------
    ValueError
        Different shapes, or no pixel to evaluate (an empty disparity or ground truth).
    """
    d = check_array(disparity, "disparity", shape=(None, None), finite=False)
    g = check_array(gt, "gt", shape=d.shape, finite=False)
    sel = np.isfinite(g) & (g > 0)
    if mask is not None:
        sel &= check_array(mask, "mask", shape=d.shape, dtype=bool)
    n = int(sel.sum())
    if n == 0:
        raise ValueError("gt: no pixel with a valid ground-truth disparity inside the mask")
    if not np.isfinite(d).any():
        raise ValueError("disparity: empty (no valid disparity anywhere)")
    valid = np.isfinite(d) & sel
    err = np.abs(d - g)
    filled = np.abs(_fill_scanlines(d) - g)
    filled = np.where(np.isfinite(filled), filled, np.abs(np.nanmedian(d) - g))
    out = {}
    nv = max(int(valid.sum()), 1)
    for t in thresholds:
        bad = (~valid & sel) | (valid & (err > t))
        out[f"bad{float(t):.1f}"] = float(100.0 * bad[sel].sum() / n)
        out[f"bad{float(t):.1f}_sparse"] = float(100.0 * (valid & (err > t)).sum() / nv)
    out["avgerr"] = float(np.where(valid, err, filled)[sel].mean())
    out["invalid"] = float(100.0 * (~valid & sel).sum() / n)
    out["density"] = 100.0 - out["invalid"]
    out["n_pixels"] = n
    return out


def nonoccluded_mask(gt_left: np.ndarray, gt_right: np.ndarray, *, tol: float = 1.0
                     ) -> np.ndarray:
    """Pixels of the left view also visible in the right view (rectified frames).

    A left pixel ``x`` with ground-truth disparity ``d`` is non-occluded when the right
    view's ground truth at ``x - d`` agrees with ``d`` to within ``tol`` pixels.

    Parameters
    ----------
    gt_left, gt_right : (H, W) float
        Ground-truth disparities of each rectified view (positive; the right one at
        right pixels); NaN or <= 0 where unknown.
    """
    gl = check_array(gt_left, "gt_left", shape=(None, None), finite=False)
    gr = check_array(gt_right, "gt_right", shape=gl.shape, finite=False)
    H, W = gl.shape
    ok = np.isfinite(gl) & (gl > 0)
    xr = np.round(np.arange(W)[None, :] - np.where(ok, gl, 0)).astype(np.int64)
    ok &= (xr >= 0) & (xr < W)
    rows = np.broadcast_to(np.arange(H)[:, None], (H, W))
    g2 = np.full((H, W), np.nan)
    g2[ok] = gr[rows[ok], xr[ok]]
    return ok & np.isfinite(g2) & (np.abs(g2 - gl) <= tol)
