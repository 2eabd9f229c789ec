"""Laser speckle with a physical grain: the subjective speckle an imaging lens forms.

Coherent light scattered by a rough surface reaches the sensor as a circular complex
Gaussian field band-limited by the lens pupil; its intensity is fully developed speckle
(exponential statistics, contrast 1) whose grains are the size of the lens's Airy disc on
the sensor, ``d = 2.44 lambda N`` (wavelength times f-number; Goodman, *Speckle Phenomena
in Optics*, 2007, ch. 5): the intensity's correlation falls to zero at the Airy radius
``d / 2``. The field is drawn on a grid fine enough that the intensity is not aliased,
shaped by the pupil (the coherent cut-off ``1 / (2 lambda N) = 1.22 / d`` in spatial
frequency) and integrated over each pixel: grains smaller
than a pixel average out and lower the contrast, as on a real sensor. ``contrast``
(below 1: partially developed speckle, a surface smoother than the wavelength or light
not fully coherent) blends it with a uniform image: ``1 + contrast (I - 1)``.

The triangulation error speckle causes grows with the grain (Dorsch, Hausler and
Herrmann, "Laser triangulation: fundamental uncertainty in distance measurement",
Applied Optics 33(7), 1994): the stripe's centroid jitters by a fraction of a grain.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from core.validate import check_range

__all__ = ["grain_px", "speckle_field", "intensity_covariance"]


def grain_px(wavelength_nm: float, f_number: float, pixel_pitch_um: float) -> float:
    """Mean speckle grain diameter on the sensor in pixels: ``2.44 lambda N / pitch``."""
    return 2.44 * wavelength_nm * 1e-3 * f_number / pixel_pitch_um


def speckle_field(shape: tuple[int, int], grain: float, contrast: float,
                  rng: np.random.Generator) -> np.ndarray:
    """A unit-mean multiplicative speckle image ``(h, w)`` of grain diameter ``grain``
    pixels and (sub-pixel) ``contrast``, pixel-integrated (see the module docstring)."""
    h, w = (int(x) for x in shape)
    grain = check_range(grain, "grain", 0.0, None, lo_open=True)
    contrast = check_range(contrast, "contrast", 0.0, 2.0)
    s = max(1, int(np.ceil(4.0 * 1.22 / grain)))          # intensity band below Nyquist
    H, W = h * s, w * s
    noise = rng.standard_normal((H, W)) + 1j * rng.standard_normal((H, W))
    fc = 1.22 / (grain * s)                                 # pupil cut-off, cycles/sample
    fy = np.fft.fftfreq(H)[:, None]
    fx = np.fft.fftfreq(W)[None, :]
    field = np.fft.ifft2(np.fft.fft2(noise) * ((fx * fx + fy * fy) <= fc * fc))
    inten = np.abs(field) ** 2
    inten /= inten.mean()
    inten = np.clip(1.0 + contrast * (inten - 1.0), 0.0, None)
    return inten.reshape(h, s, w, s).mean(axis=(1, 3))


@lru_cache(maxsize=32)
def _covariance(grain: float, lags: int, nodes: int) -> np.ndarray:
    from scipy.special import j1

    fc = 1.22 / grain
    t = np.linspace(-1.0, 1.0, nodes)
    w = 1.0 - np.abs(t)            # a pixel's box correlated with itself: a triangle
    w /= w.sum()
    out = np.empty(lags)
    for k in range(lags):
        a = 2.0 * np.pi * fc * np.hypot(k + t[:, None], t[None, :])
        safe = np.where(a > 1e-9, a, 1.0)
        mu = np.where(a > 1e-9, 2.0 * j1(safe) / safe, 1.0)
        out[k] = float(np.sum(mu * mu * w[:, None] * w[None, :]))
    out.setflags(write=False)
    return out


def intensity_covariance(grain: float, lags: int, *, nodes: int = 241) -> np.ndarray:
    """``(lags,)``: the covariance of fully developed, pixel-integrated speckle of unit
    mean between two pixels ``0, 1, ..., lags - 1`` apart along a row, for grains of
    diameter ``grain`` pixels (:func:`speckle_field` with contrast 1). The intensity's
    correlation is the squared field correlation ``[2 J1(x) / x]^2``,
    ``x = 2 pi (1.22 / grain) r`` (Goodman 2007, ch. 5); integrated over two pixels it is
    averaged with the triangle that is a box correlated with itself, in both directions.
    Element 0 is the per-pixel variance (the squared contrast): 0.36 at 1.84 px, toward 1
    for grains much larger than a pixel. Times ``contrast^2`` for partly developed speckle."""
    grain = check_range(grain, "grain", 0.0, None, lo_open=True)
    return _covariance(float(grain), int(lags), int(nodes))
