"""Error propagation: depth noise of a laser triangulator from its peak-localization noise.

A point is the camera ray through the stripe's sub-pixel column ``u`` met with the
laser plane; a peak error ``du`` moves it along the plane. To first order the depth
(camera z) error is ``dz = (dz/du) du`` with the derivative of the ray-plane
intersection, so ``sigma_z = |dz/du| sigma_peak``. For a ray near the optical axis,
a plane at triangulation angle ``theta`` to it and a pixel footprint ``Z / f``:

    sigma_z = sigma_peak * (Z / f) / tan(theta)

(Dorsch, Hausler & Herrmann 1994 for the speckle limit; any triangulation text for the
geometry). :func:`depth_sigma` evaluates the exact derivative per point;
:func:`closed_form_sigma_z` the formula above.

Where ``sigma_peak`` comes from (:func:`peak_sigma_model`, per detected peak):

* sensor noise (shot + read) and quantization (1/12 DN^2) of every sample of the row,
  and speckle (multiplicative, contrast ``C``), propagated to first order through the
  detector by its numerical Jacobian with respect to the samples. Speckle of grain ``d``
  px is correlated over neighbouring samples: its covariance is
  ``C^2 f_j f_k kappa(|j - k|)`` (the pixel-integrated intensity covariance of
  :func:`acquire.render.speckle.intensity_covariance`); without a grain it is independent per
  pixel, variance ``(C f)^2``. First order holds for weak speckle: against Monte Carlo
  at contrast 0.2 within 12 % (``tests/test_laser_error_model.py``); at full contrast it
  over-predicts by 1.3-1.7x (the detector's non-linear response to a deep modulation);
* surface texture under the stripe: an albedo ``a(u)`` multiplies the Gaussian profile
  of width ``sigma_w`` px; with ``g = d ln a / du`` that is a Gaussian shifted by
  ``g sigma_w^2`` (exactly, to first order in the gradient), invisible in the profile
  itself -- every unbiased detector reports the shifted peak. ``sigma_w`` (the sheet's
  thickness in pixels) comes from each peak, the spread of ``g`` from the ambient-lit
  flanks of the stripe (:func:`log_albedo_gradient`), its noise variance subtracted.

:func:`estimate_peak_sigma` (the row-to-row jitter of the stripe) is kept as a data-only
cross-check; it misses every error correlated over more rows than its window.

References
----------
R. G. Dorsch, G. Hausler, J. M. Herrmann, "Laser triangulation: fundamental
uncertainty in distance measurement", Applied Optics 33(7), 1994,
doi:10.1364/AO.33.001306.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from reconstruct.laser.calibration import intersect_rays_plane, pixel_rays
from reconstruct.laser.stripe import _METHOD_CODE, StripeOptions, _row_peak

__all__ = ["estimate_peak_sigma", "depth_sigma", "closed_form_sigma_z", "pixel_variance",
           "peak_sigma_model", "log_albedo_gradient", "PeakErrorAccumulator"]


def pixel_variance(image: np.ndarray, sensor: dict, *, speckle: float = 0.0) -> np.ndarray:
    """Variance (DN^2) ``(h, w)`` of each pixel under the sensor model of
    :class:`acquire.sensor.Sensor` (shot + read noise, quantization) plus speckle.

    ``sensor`` is the capture's sensor record (``gain``, ``full_well``, ``read_noise``,
    ``bit_depth``, ``shot_noise``). ``speckle`` is the laser's speckle contrast; it is
    applied to the whole level (an upper bound: the ambient part has none).
    """
    f = np.asarray(image, np.float64)
    q = sensor["gain"] * (2 ** int(sensor["bit_depth"]) - 1) / sensor["full_well"]  # DN / e-
    v = (q * sensor["read_noise"]) ** 2 + 1.0 / 12.0 + np.zeros_like(f)
    if sensor.get("shot_noise", True):
        v += np.maximum(f, 0.0) * q
    if speckle > 0:
        v += (speckle * f) ** 2
    return v


_JUMP_PX = 0.05
_HALF = 5   # the detector's Jacobian is taken over the 2 * _HALF + 1 samples at the peak


@numba.njit(cache=True, nogil=True)
def _peak_model(img, var, cols, method, th, mc, wmin, wmax, steep, w, sat, amb, out_var,
                out_w2, out_jac, out_j0):
    h, n = img.shape
    row = np.empty(n, np.float64)
    for r in range(h):
        out_var[r] = np.nan
        out_w2[r] = np.nan
        out_j0[r] = -1
        for k in range(out_jac.shape[1]):
            out_jac[r, k] = 0.0
        c = cols[r]
        if not np.isfinite(c):
            continue
        for j in range(n):
            row[j] = img[r, j]
        imax = 0
        for j in range(1, n):
            if row[j] > row[imax]:
                imax = j
        acc = 0.0
        out_j0[r] = max(imax - _HALF, 0)
        for j in range(max(imax - _HALF, 0), min(imax + _HALF + 1, n)):
            # one-sided differences with a small step: integer samples tie often, and a
            # tie broken by the step moves the detector's centre sample (a jump, not a
            # slope); the smaller of the two one-sided slopes is the smooth one
            step = 1e-3 * (math.sqrt(var[r, j]) + 0.05)
            old = row[j]
            row[j] = old + step
            cp, _ = _row_peak(row, method, th, mc, wmin, wmax, steep, w, sat, amb)
            row[j] = old - step
            cm, _ = _row_peak(row, method, th, mc, wmin, wmax, steep, w, sat, amb)
            row[j] = old
            # a detection that moves by more than a hair under a 1e-3 sigma nudge has
            # jumped (another peak, or an accept/reject test flipped): not a slope
            dp = (cp - c) / step if np.isfinite(cp) and abs(cp - c) < _JUMP_PX else np.inf
            dm = (c - cm) / step if np.isfinite(cm) and abs(c - cm) < _JUMP_PX else np.inf
            d = dp if abs(dp) < abs(dm) else dm
            if np.isfinite(d):
                acc += d * d * var[r, j]
                out_jac[r, j - out_j0[r]] = d
        out_var[r] = acc
        if 1 <= imax < n - 1:
            base = row[imax]
            for j in range(max(imax - w, 0), min(imax + w + 1, n)):
                base = min(base, row[j])
            fm = row[imax - 1] - base
            f0 = row[imax] - base
            fp = row[imax + 1] - base
            if fm > 0 and fp > 0 and f0 > 0:
                den = math.log(fm) - 2 * math.log(f0) + math.log(fp)
                if den < 0:
                    out_w2[r] = -1.0 / den


def peak_sigma_model(image: np.ndarray, cols: np.ndarray, variance: np.ndarray, *,
                     options: StripeOptions, speckle: float = 0.0,
                     speckle_grain: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Noise part of the peak error and the stripe's width, per row.

    Speckle with a grain (``speckle_grain`` > 0 px, contrast ``speckle``) is correlated
    between neighbouring samples: it is propagated here with its covariance along the row
    (:func:`acquire.render.speckle.intensity_covariance`, times ``speckle^2 f_j f_k``), and is
    then not part of ``variance``. Without a grain, speckle is independent per pixel and
    belongs in ``variance`` (:func:`pixel_variance`).

    Parameters
    ----------
    image : (h, w) array
        The frame the peaks ``cols`` were detected in.
    cols : (h,) float64
        :func:`reconstruct.laser.stripe.detect_peaks` output (NaN = no peak).
    variance : (h, w) float64
        :func:`pixel_variance` of the frame.
    options : StripeOptions
        The detector and thresholds used.

    Returns
    -------
    sigma_noise : (h,) float64
        Standard deviation (px) of the detected column from the samples' noise
        (numerical Jacobian of the detector, the smaller one-sided slope); NaN without a peak.
    sigma_w : (h,) float64
        Gaussian width (px) of the stripe from its three top samples; NaN if not
        measurable.
    """
    img = np.ascontiguousarray(np.asarray(image, np.float64))
    h, n = img.shape
    v = np.empty(h)
    w2 = np.empty(h)
    jac = np.empty((h, 2 * _HALF + 1))
    j0 = np.empty(h, np.int64)
    _peak_model(img, np.ascontiguousarray(variance, dtype=np.float64),
                np.asarray(cols, np.float64), _METHOD_CODE[options.method],
                float(options.threshold), float(options.min_contrast), float(options.min_width),
                float(options.max_width), float(options.max_steepness), int(options.window),
                float(options.saturation),
                float(options.ambiguity), v, w2, jac, j0)
    if speckle > 0 and speckle_grain > 0:
        from acquire.render.speckle import intensity_covariance

        k = jac.shape[1]
        lag = np.abs(np.arange(k)[:, None] - np.arange(k)[None, :])
        cov = speckle ** 2 * intensity_covariance(speckle_grain, k)[lag]
        r = np.flatnonzero(j0 >= 0)
        idx = np.minimum(j0[r, None] + np.arange(k)[None, :], n - 1)
        jf = jac[r] * img[r[:, None], idx]         # d(peak)/d(speckle factor) per sample
        v[r] += np.einsum("ri,ij,rj->r", jf, cov, jf)
    return np.sqrt(v), np.sqrt(w2)


def log_albedo_gradient(image: np.ndarray, cols: np.ndarray, variance: np.ndarray, *,
                        inner: int = 5, outer: int = 15,
                        floor: float = 4.0) -> tuple[float, float, int]:
    """Sums for the spread of ``g = d ln(albedo) / du`` beside the stripe.

    The ambient-lit pixels ``inner..outer`` columns either side of each row's peak show
    the albedo alone; their central log-differences give ``g`` plus noise. Returns
    ``(sum g^2, sum of the noise variance of g, count)`` over the kept pixels (brighter
    than ``floor`` DN; the 1 % largest ``|g|``, silhouettes and edges, dropped), to be
    accumulated over frames: ``sigma_g^2 = (sum g^2 - sum noise) / count``.
    """
    f = np.asarray(image, np.float64)
    r = np.flatnonzero(np.isfinite(cols))
    if r.size == 0:
        return 0.0, 0.0, 0
    c = np.round(cols[r]).astype(int)
    offs = np.concatenate([np.arange(-outer, -inner + 1), np.arange(inner, outer + 1)])
    rr = np.repeat(r, offs.size)
    uu = (c[:, None] + offs[None, :]).ravel()
    ok = (uu >= 1) & (uu < f.shape[1] - 1)
    rr, uu = rr[ok], uu[ok]
    a, b = f[rr, uu - 1], f[rr, uu + 1]
    ok = (a >= floor) & (b >= floor)
    rr, uu, a, b = rr[ok], uu[ok], a[ok], b[ok]
    if a.size == 0:
        return 0.0, 0.0, 0
    g = 0.5 * (np.log(b) - np.log(a))
    gn = 0.25 * (variance[rr, uu + 1] / b ** 2 + variance[rr, uu - 1] / a ** 2)
    keep = np.abs(g) <= np.percentile(np.abs(g), 99)
    return float(np.sum(g[keep] ** 2)), float(np.sum(gn[keep])), int(keep.sum())


class PeakErrorAccumulator:
    """Collects, frame by frame, what :func:`peak_sigma_model` and
    :func:`log_albedo_gradient` measure, then gives the per-peak ``sigma_peak``."""

    def __init__(self, sensor: dict, options: StripeOptions, *, speckle: float = 0.0,
                 speckle_grain: float = 0.0):
        self.sensor, self.options = sensor, options
        self.speckle, self.speckle_grain = speckle, speckle_grain
        self.noise, self.width = [], []
        self.g2 = self.gn = 0.0
        self.count = 0

    def add(self, image: np.ndarray, cols: np.ndarray):
        grain = self.speckle_grain > 0
        var = pixel_variance(image, self.sensor, speckle=0.0 if grain else self.speckle)
        s, w = peak_sigma_model(image, cols, var, options=self.options,
                                speckle=self.speckle if grain else 0.0,
                                speckle_grain=self.speckle_grain)
        self.noise.append(s)
        self.width.append(w)
        g2, gn, n = log_albedo_gradient(image, cols, var)
        self.g2, self.gn, self.count = self.g2 + g2, self.gn + gn, self.count + n

    @property
    def sigma_g(self) -> float:
        """Spread of the log-albedo gradient, px^-1 (0 when not measurable)."""
        if self.count == 0:
            return 0.0
        return float(np.sqrt(max(self.g2 - self.gn, 0.0) / self.count))

    def sigma_peak(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(total, noise, texture)`` each ``(f, h)`` px (NaN where no peak)."""
        noise = np.stack(self.noise)
        w = np.stack(self.width)
        w = np.where(np.isfinite(w), w, np.nanmedian(w) if np.isfinite(w).any() else 0.0)
        tex = w ** 2 * self.sigma_g
        return np.sqrt(noise ** 2 + tex ** 2), noise, tex


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
    ``pixels (n, 2)`` (column, row), for a peak noise ``sigma_peak`` px along the row
    (a scalar or ``(n,)``)."""
    dp = np.array([h, 0.0])
    z1 = intersect_rays_plane(pixel_rays(camera, pixels + dp), plane)[:, 2]
    z0 = intersect_rays_plane(pixel_rays(camera, pixels - dp), plane)[:, 2]
    return np.abs(z1 - z0) / (2 * h) * sigma_peak


def closed_form_sigma_z(sigma_peak: float, depth: float, focal_px: float,
                        triangulation_angle: float) -> float:
    """``sigma_peak * (depth / focal_px) / tan(triangulation_angle)`` (angle in radians)."""
    return float(sigma_peak * depth / focal_px / np.tan(triangulation_angle))
