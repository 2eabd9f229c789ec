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

import numpy as np

from core.validate import check_range

__all__ = ["grain_px", "speckle_field"]


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
