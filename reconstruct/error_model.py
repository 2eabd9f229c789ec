"""Error propagation: depth noise of a laser triangulator from its peak-localization noise.

A point is the camera ray through the stripe's sub-pixel column ``u`` met with the
laser plane; a peak error ``du`` moves it along the plane. To first order the depth
(camera z) error is ``dz = (dz/du) du`` with the derivative of the ray-plane
intersection, so ``sigma_z = |dz/du| sigma_peak``. For a ray near the optical axis,
a plane at triangulation angle ``theta`` to it and a pixel footprint ``Z / f``:

    sigma_z = sigma_peak * (Z / f) / tan(theta)

(Dorsch, Hausler & Herrmann 1994 for the speckle limit; any triangulation text for the
geometry). :func:`depth_sigma` evaluates the exact derivative per point;
:func:`closed_form_sigma_z` the formula above; :func:`estimate_peak_sigma` measures
``sigma_peak`` from the data alone (the jitter of the stripe from row to row).

References
----------
R. G. Dorsch, G. Hausler, J. M. Herrmann, "Laser triangulation: fundamental
uncertainty in distance measurement", Applied Optics 33(7), 1994,
doi:10.1364/AO.33.001306.
"""

from __future__ import annotations

import numpy as np

from reconstruct.laser_calib import intersect_rays_plane, pixel_rays

__all__ = ["estimate_peak_sigma", "depth_sigma", "closed_form_sigma_z"]


def estimate_peak_sigma(cols: np.ndarray, *, half: int = 3) -> float:
    """Peak-localization noise (px) from stripe columns ``(f, h)`` (NaN = no peak).

    Along a smooth surface the stripe column is a smooth function of the row. The
    residual of each column from a quadratic fitted over its ``2 * half + 1`` rows has
    variance ``(1 - leverage) sigma^2`` for independent errors of standard deviation
    sigma; a robust (MAD) scale of the residuals over all frames estimates sigma. Errors
    correlated over more rows than the window (albedo texture, calibration) are not
    counted: they are systematic, not noise.
    """
    c = np.atleast_2d(np.asarray(cols, float))
    m = 2 * half + 1
    x = np.arange(-half, half + 1, dtype=float)
    X = np.stack([np.ones(m), x, x * x], axis=1)
    Hc = X @ np.linalg.pinv(X)  # hat matrix; row `half` predicts the centre
    w = np.eye(m)[half] - Hc[half]
    if c.shape[1] < m:
        return float("nan")
    win = np.lib.stride_tricks.sliding_window_view(c, m, axis=1)
    r = win @ w
    r = r[np.isfinite(r)]
    if r.size < 10:
        return float("nan")
    mad = np.median(np.abs(r - np.median(r)))
    return float(1.4826 * mad / np.sqrt(w @ w))


def depth_sigma(camera, plane: np.ndarray, pixels: np.ndarray, sigma_peak: float, *,
                h: float = 0.05) -> np.ndarray:
    """Predicted z-depth standard deviation ``(n,)`` of the points triangulated at
    ``pixels (n, 2)`` (column, row), for a peak noise ``sigma_peak`` px along the row."""
    dp = np.array([h, 0.0])
    z1 = intersect_rays_plane(pixel_rays(camera, pixels + dp), plane)[:, 2]
    z0 = intersect_rays_plane(pixel_rays(camera, pixels - dp), plane)[:, 2]
    return np.abs(z1 - z0) / (2 * h) * sigma_peak


def closed_form_sigma_z(sigma_peak: float, depth: float, focal_px: float,
                        triangulation_angle: float) -> float:
    """``sigma_peak * (depth / focal_px) / tan(triangulation_angle)`` (angle in radians)."""
    return float(sigma_peak * depth / focal_px / np.tan(triangulation_angle))
