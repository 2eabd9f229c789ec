"""Speckle with a physical grain (issue 17): unit mean, fully developed contrast when the
grains are larger than a pixel and less when the pixels average them, grains of the
Airy-disc size, seeded; and on a scan, the stripe jitters more as the grain grows
(Dorsch, Hausler and Herrmann 1994)."""

import numpy as np
import pytest

from acquire.laser.sheet import LaserRenderer
from acquire.render.materials import Material
from acquire.render.speckle import grain_px, speckle_field
from data_synth.plates import laser_plate
from reconstruct.laser.stripe import StripeOptions, detect_peaks


def _corr(img, lag):
    a = img - img.mean()
    return float((a[:, :-lag] * a[:, lag:]).mean() / a.var())


def test_grain_size_contrast_and_seed():
    assert grain_px(650.0, 4.0, 3.45) == pytest.approx(2.44 * 0.65 * 4 / 3.45)
    big = speckle_field((256, 256), 8.0, 1.0, np.random.default_rng(0))
    assert big.mean() == pytest.approx(1.0, abs=0.05)
    assert big.std() == pytest.approx(1.0, abs=0.12)           # fully developed
    # intensity correlation [2 J1(x)/x]^2: 0.37 at a quarter grain, 0 past the Airy radius
    assert _corr(big, 2) > 0.25 and abs(_corr(big, 12)) < 0.1
    fine = speckle_field((256, 256), 0.8, 1.0, np.random.default_rng(0))
    assert fine.std() < 0.6                                    # sub-pixel grains average out
    again = speckle_field((256, 256), 8.0, 1.0, np.random.default_rng(0))
    assert again.tobytes() == big.tobytes()
    half = speckle_field((256, 256), 8.0, 0.5, np.random.default_rng(0))
    assert half.std() == pytest.approx(0.5 * big.std(), rel=0.05)


def test_the_stripe_jitters_more_with_larger_grains():
    def jitter(grain):
        lp = laser_plate(Material(albedo=np.full(3, 0.9)), incidence_deg=30.0,
                         view_deg=30.0, height=160)
        lp.laser.speckle, lp.laser.speckle_grain = 1.0, grain
        r = LaserRenderer(lp.scene, lp.camera)
        fr = r.frame(lp.camera.cam_from_world, lp.laser, rng=np.random.default_rng(1))
        img = fr.radiance.astype(float)
        cols, _ = detect_peaks(img * 200 / img.max(), options=StripeOptions(
            method="gaussian", max_width=60, threshold=5, min_contrast=3))
        return float(np.nanstd(cols))

    assert jitter(1.0) < jitter(3.0) < jitter(8.0)
