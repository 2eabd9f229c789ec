"""Sub-pixel laser-stripe extraction: one peak per image row.

The stripe of a sheet-of-light scanner crosses every row of the image at most
once (for the usual rig, the sheet is roughly parallel to the image columns), so
extraction is a per-row search: the row's maximum locates the stripe to the
pixel, a small window around it refines to sub-pixel. The detectors are the
classic ones compared by Fisher & Naidu (1996):

``"argmax"``
    the integer maximum (no refinement; the baseline that the others beat).
``"com"``
    centre of mass of the baseline-subtracted intensities of the contiguous run
    above a fraction of the peak contrast.
``"gaussian"``
    three-point Gaussian fit: the vertex of the parabola through the logarithms of
    the three samples around the maximum (exact for a sampled Gaussian).
``"parabolic"``
    three-point parabola fit on the intensities.
``"blais_rioux"``
    zero crossing, linearly interpolated, of the fourth-order derivative filter
    ``g(i) = f(i-2) + f(i-1) - f(i+1) - f(i+2)`` (Blais & Rioux 1986).

Saturation: a peak whose maximum reaches ``saturation`` is located by a
least-squares Gaussian through its unclipped flank samples (the half-contrast
midpoint as a fallback), where every three-point fit breaks down.

Rejection of spurious peaks: a row gives no peak when the maximum is below
``threshold``, when its contrast above the local baseline is below
``min_contrast``, when its full width at half contrast lies outside
``[min_width, max_width]`` pixels (a hot pixel or speckle spike is too narrow, a
specular highlight or ambient blob too wide), when either edge of the
half-contrast run falls faster than ``max_steepness`` times the steepest slope a
sampled Gaussian of that width allows, ``contrast / (sigma sqrt(e))`` per pixel with
``sigma = FWHM / 2.355`` (an ambient-lit plateau or step edge: a thin lit part against
a dark background, an albedo band; 0 = off), or, with ``ambiguity`` > 0, when a
second peak farther than ``window`` pixels has at least ``ambiguity`` times its
contrast.

References
----------
F. Blais, M. Rioux, "Real-time numerical peak detector", Signal Processing 11(2),
1986, doi:10.1016/0165-1684(86)90033-2.
R. B. Fisher, D. K. Naidu, "A comparison of algorithms for subpixel peak
detection", in Image Technology, Springer 1996, doi:10.1007/978-3-642-58288-2_15.

>>> import numpy as np
>>> u = np.arange(64.0)
>>> img = (200 * np.exp(-0.5 * ((u - 30.3) / 1.5) ** 2))[None, :].repeat(2, 0)
>>> cols, _ = detect_peaks(img, method="gaussian")
>>> np.round(cols, 6).tolist()
[30.3, 30.3]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from core.validate import check_choice, check_positive, check_range

__all__ = ["DETECTORS", "StripeOptions", "detect_peaks", "argmax_peaks"]

DETECTORS = ("argmax", "com", "gaussian", "parabolic", "blais_rioux")
_METHOD_CODE = {name: i for i, name in enumerate(DETECTORS)}


@dataclass(frozen=True)
class StripeOptions:
    """Options of :func:`detect_peaks` (see the module docstring for their meaning).

    Intensities are in the image's own units (0-255 for 8-bit frames).
    """

    method: str = "gaussian"
    threshold: float = 20.0
    min_contrast: float = 12.0
    min_width: float = 1.5
    max_width: float = 12.0
    max_steepness: float = 1.5
    window: int = 8
    saturation: float = 255.0
    ambiguity: float = 0.0

    def __post_init__(self):
        check_choice(self.method, "method", DETECTORS)
        check_positive(self.threshold, "threshold", allow_zero=True)
        check_positive(self.min_contrast, "min_contrast")
        check_positive(self.min_width, "min_width", allow_zero=True)
        check_range(self.max_width, "max_width", self.min_width, None, lo_open=True)
        check_positive(self.max_steepness, "max_steepness", allow_zero=True)
        if int(self.window) != self.window or not 2 <= self.window <= 64:
            raise ValueError(f"window: expected an integer in [2, 64], got {self.window!r}")
        check_positive(self.saturation, "saturation")
        check_range(self.ambiguity, "ambiguity", 0.0, 1.0)


@numba.njit(cache=True, nogil=True)
def _row_peak(f, method, threshold, min_contrast, min_width, max_width, max_steepness, w,
              sat, ambiguity):
    n = f.shape[0]
    # 1. integer maximum (first occurrence)
    imax = 0
    vmax = f[0]
    for j in range(1, n):
        if f[j] > vmax:
            vmax = f[j]
            imax = j
    if vmax < threshold:
        return math.nan, 0.0
    # 2. local baseline: the lower of the minima of the window's two flanks
    a = max(imax - w, 0)
    b = min(imax + w, n - 1)
    left = vmax
    for j in range(a, imax + 1):
        left = min(left, f[j])
    right = vmax
    for j in range(imax, b + 1):
        right = min(right, f[j])
    base = min(left, right)
    contrast = vmax - base
    if contrast < min_contrast:
        return math.nan, 0.0
    # 3. width at half contrast, with interpolated crossings (also the saturated estimate)
    half = base + 0.5 * contrast
    jl = imax
    while jl > a and f[jl - 1] >= half:
        jl -= 1
    if jl == a and f[jl] >= half and a > 0:
        return math.nan, 0.0  # still above half contrast at the window's edge: too wide
    if jl == a and f[jl] >= half:
        xl = float(a) - 0.5
    else:
        # crossing between jl - 1 (below) and jl (above)
        xl = jl - (f[jl] - half) / (f[jl] - f[jl - 1])
    jr = imax
    while jr < b and f[jr + 1] >= half:
        jr += 1
    if jr == b and f[jr] >= half and b < n - 1:
        return math.nan, 0.0
    if jr == b and f[jr] >= half:
        xr = float(b) + 0.5
    else:
        xr = jr + (f[jr] - half) / (f[jr] - f[jr + 1])
    width = xr - xl
    if width < min_width or width > max_width:
        return math.nan, 0.0
    # 3b. profile test: a sampled Gaussian of this FWHM falls by at most its steepest
    # slope, contrast / (sigma sqrt(e)), per pixel; a lit plateau (a thin ambient-lit
    # part against a dark background, an albedo band) drops from above half contrast
    # to the baseline in one pixel on both sides. Skipped for clipped peaks, whose
    # plateau is the sensor's, and at the image border.
    if max_steepness > 0.0 and vmax < sat and jl > 0 and jr < n - 1:
        slope = min(1.0, 2.3548200450309493 / (width * math.sqrt(math.e)))
        edge = max(f[jl] - f[jl - 1], f[jr] - f[jr + 1]) / contrast
        if edge > max_steepness * slope:
            return math.nan, 0.0
    # 4. optional ambiguity test: a second, separate peak nearly as strong
    if ambiguity > 0.0:
        second = base
        for j in range(n):
            if (j < imax - w or j > imax + w) and f[j] > second:
                second = f[j]
        if second - base >= ambiguity * contrast:
            return math.nan, 0.0
    # 5. sub-pixel refinement
    if method == 0 or imax < 2 or imax > n - 3:
        return float(imax), contrast
    if vmax >= sat:
        # clipped plateau: least-squares Gaussian (parabola in log) through the unclipped
        # flank samples; fall back to the half-level midpoint
        s0 = s1 = s2 = s3 = s4 = t0 = t1 = t2 = 0.0
        cnt = 0
        for j in range(a, b + 1):
            v = f[j] - base
            if f[j] < sat and v > 0.1 * contrast:
                x = float(j - imax)
                lv = math.log(v)
                wt = v * v  # log-domain weights: noise of log(v) ~ 1/v
                s0 += wt
                s1 += wt * x
                s2 += wt * x * x
                s3 += wt * x * x * x
                s4 += wt * x * x * x * x
                t0 += wt * lv
                t1 += wt * x * lv
                t2 += wt * x * x * lv
                cnt += 1
        if cnt >= 4:
            # solve the 3x3 normal equations [s0 s1 s2; s1 s2 s3; s2 s3 s4] [c0 c1 c2] = t
            det = (s0 * (s2 * s4 - s3 * s3) - s1 * (s1 * s4 - s3 * s2)
                   + s2 * (s1 * s3 - s2 * s2))
            if abs(det) > 1e-12:
                c1 = (s0 * (t1 * s4 - s3 * t2) - t0 * (s1 * s4 - s3 * s2)
                      + s2 * (s1 * t2 - t1 * s2)) / det
                c2 = (s0 * (s2 * t2 - t1 * s3) - s1 * (s1 * t2 - t1 * s2)
                      + t0 * (s1 * s3 - s2 * s2)) / det
                if c2 < 0.0:
                    d = -c1 / (2.0 * c2)
                    if abs(d) <= 0.5 * (xr - xl) + 1.0:
                        return imax + d, contrast
        return 0.5 * (xl + xr), contrast
    fm = f[imax - 1] - base
    f0 = vmax - base
    fp = f[imax + 1] - base
    if method == 1:  # centre of mass over the contiguous run above 20 % of the contrast
        cut = 0.2 * contrast
        s0 = 0.0
        s1 = 0.0
        j = imax
        while j >= a and f[j] - base > cut:
            v = f[j] - base - cut
            s0 += v
            s1 += v * j
            j -= 1
        j = imax + 1
        while j <= b and f[j] - base > cut:
            v = f[j] - base - cut
            s0 += v
            s1 += v * j
            j += 1
        return s1 / s0, contrast
    if method == 2:  # Gaussian three-point
        eps = 1e-3
        lm = math.log(max(fm, eps))
        l0 = math.log(max(f0, eps))
        lp = math.log(max(fp, eps))
        den = lm - 2.0 * l0 + lp
        if den >= 0.0:
            return float(imax), contrast
        d = 0.5 * (lm - lp) / den
        return imax + max(-0.5, min(0.5, d)), contrast
    if method == 3:  # parabolic three-point
        den = fm - 2.0 * f0 + fp
        if den >= 0.0:
            return float(imax), contrast
        d = 0.5 * (fm - fp) / den
        return imax + max(-0.5, min(0.5, d)), contrast
    # method 4: Blais-Rioux fourth-order derivative zero crossing
    # g ~ -6 f': negative left of the peak, positive right of it
    g0 = f[imax - 2] + f[imax - 1] - f[imax + 1] - f[imax + 2]
    if g0 <= 0.0:  # crossing in [imax, imax + 1]
        g1 = f[imax - 1] + f[imax] - f[imax + 2] - f[min(imax + 3, n - 1)]
        if g1 - g0 <= 0.0:
            return float(imax), contrast
        return imax - g0 / (g1 - g0), contrast
    gm = f[max(imax - 3, 0)] + f[imax - 2] - f[imax] - f[imax + 1]  # crossing in [imax - 1, imax]
    if g0 - gm <= 0.0:
        return float(imax), contrast
    return imax - 1 - gm / (g0 - gm), contrast


@numba.njit(cache=True, nogil=True)
def _peaks(img, method, threshold, min_contrast, min_width, max_width, max_steepness, w, sat,
           ambiguity):
    h = img.shape[0]
    cols = np.empty(h, np.float64)
    contrast = np.empty(h, np.float32)
    row = np.empty(img.shape[1], np.float64)
    for r in range(h):
        for j in range(img.shape[1]):
            row[j] = img[r, j]
        c, k = _row_peak(row, method, threshold, min_contrast, min_width, max_width,
                         max_steepness, w, sat, ambiguity)
        cols[r] = c
        contrast[r] = k
    return cols, contrast


def detect_peaks(image: np.ndarray, *, method: str = "gaussian",
                 options: StripeOptions | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Sub-pixel column of the stripe in each row of ``image``.

    Parameters
    ----------
    image : (h, w) uint8, uint16 or float
        A single-channel frame (take the laser's colour channel, or a laser-on minus
        laser-off difference, before calling).
    method : str
        One of ``DETECTORS``; ignored when ``options`` is given.
    options : StripeOptions, optional
        Thresholds and window; ``options.method`` wins over ``method``.

    Returns
    -------
    cols : (h,) float64
        Sub-pixel column of the peak (pixel centres at integers), NaN where the row has
        no acceptable peak.
    contrast : (h,) float32
        Peak height above the local baseline (0 where rejected).
    """
    opt = options if options is not None else StripeOptions(method=method)
    img = np.asarray(image)
    if img.ndim != 2:
        raise ValueError(f"image: expected a single-channel (h, w) array, got shape {img.shape}")
    if img.shape[1] < 5:
        raise ValueError(f"image: expected at least 5 columns, got {img.shape[1]}")
    return _peaks(np.ascontiguousarray(img), _METHOD_CODE[opt.method], float(opt.threshold),
                  float(opt.min_contrast), float(opt.min_width), float(opt.max_width),
                  float(opt.max_steepness), int(opt.window), float(opt.saturation),
                  float(opt.ambiguity))


def argmax_peaks(image: np.ndarray) -> np.ndarray:
    """The plain per-row argmax (the speed peer of :func:`detect_peaks`): (h,) int64."""
    return np.argmax(np.asarray(image), axis=1)
