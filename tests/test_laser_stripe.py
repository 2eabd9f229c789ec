"""Sub-pixel stripe detectors against sampled Gaussian profiles with known centres."""

import numpy as np
import pytest

from reconstruct.stripe import DETECTORS, StripeOptions, argmax_peaks, detect_peaks


def _profiles(rng, sigma, n=200, w=120, amp=200.0, base=10.0):
    c = rng.uniform(20, w - 20, n)
    u = np.arange(w, dtype=float)
    return base + amp * np.exp(-0.5 * ((u[None] - c[:, None]) / sigma) ** 2), c


# one-sided bias bounds (px) on noise-free, point-sampled Gaussians of sigma 1-2 px;
# the Gaussian three-point fit is exact for them (Fisher & Naidu 1996) up to the
# baseline, taken as a window minimum that still holds a little of the tails
BOUNDS = {"gaussian": 1e-3, "blais_rioux": 0.05, "com": 0.05, "parabolic": 0.08,
          "argmax": 0.5 + 1e-9}


@pytest.mark.parametrize("method", DETECTORS)
@pytest.mark.parametrize("sigma", [1.0, 1.5, 2.0])
def test_detector_bias(method, sigma, rng):
    img, c = _profiles(rng, sigma)
    cols, contrast = detect_peaks(img, method=method)
    assert np.all(np.isfinite(cols))
    assert np.max(np.abs(cols - c)) <= BOUNDS[method]
    assert np.all(contrast > 150)


@pytest.mark.parametrize("method", ["gaussian", "blais_rioux", "com"])
def test_detectors_beat_argmax_under_noise(method, rng):
    img, c = _profiles(rng, 1.5)
    noisy = np.clip(np.round(img + rng.normal(0, 2.0, img.shape)), 0, 255).astype(np.uint8)
    sub = detect_peaks(noisy, method=method)[0]
    arg = argmax_peaks(noisy)
    rms_sub = np.sqrt(np.mean((sub - c) ** 2))
    rms_arg = np.sqrt(np.mean((arg - c) ** 2))
    assert rms_sub < 0.1 < rms_arg  # argmax: uniform error, rms ~ 0.29 px


def test_saturated_peak_fits_the_flanks(rng):
    img, c = _profiles(rng, 2.0, amp=600.0)
    img = np.minimum(img, 255.0)  # clipped plateau: three-point fits would snap to its edge
    cols, _ = detect_peaks(img, method="gaussian")
    assert np.max(np.abs(cols - c)) < 0.05


def test_spurious_peaks_rejected():
    w = 100
    img = np.full((4, w), 10.0)
    img[0, 40] = 250.0  # hot pixel: narrower than min_width
    img[1, 20:70] = 200.0  # broad blob: wider than max_width
    img[2] += 8 * np.exp(-0.5 * ((np.arange(w) - 50) / 1.5) ** 2)  # too faint
    u = np.arange(w)
    img[3] = 10 + 150 * np.exp(-0.5 * ((u - 33.25) / 1.5) ** 2)
    cols, contrast = detect_peaks(img, options=StripeOptions(method="gaussian"))
    assert np.isnan(cols[:3]).all() and np.all(contrast[:3] == 0)
    assert abs(cols[3] - 33.25) < 1e-6


def test_ambiguity_rejects_two_stripes():
    u = np.arange(100.0)
    row = 10 + 150 * np.exp(-0.5 * ((u - 30) / 1.5) ** 2)
    img = (row + 140 * np.exp(-0.5 * ((u - 70) / 1.5) ** 2))[None]
    assert np.isfinite(detect_peaks(img)[0][0])
    assert np.isnan(detect_peaks(img, options=StripeOptions(ambiguity=0.8))[0][0])


def test_options_validated():
    with pytest.raises(ValueError, match="method"):
        StripeOptions(method="nope")
    with pytest.raises(ValueError, match="image"):
        detect_peaks(np.zeros((4, 5, 3)))
