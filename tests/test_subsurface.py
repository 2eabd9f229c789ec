"""Subsurface scattering (issue 17): the dipole conserves what it is given, tends to a
Lambertian surface, and a laser stripe on a translucent plate widens and shifts inward
by the closed-form amount of the shifted-source model, growing with the mean free path
and the incidence (Godin et al. 2001 on marble)."""

import numpy as np
import pytest

from acquire.laser import LaserRenderer
from acquire.materials import Material
from acquire.subsurface import Dipole, line_profile, stripe_radiance
from data_synth.plates import laser_plate
from reconstruct.stripe import StripeOptions, detect_peaks


@pytest.mark.parametrize("albedo, mfp", [(0.9, 1e-3), (0.5, 3e-4), (0.2, 5e-3)])
def test_the_dipole_reflects_exactly_its_albedo(albedo, mfp):
    d = Dipole(albedo, mfp)
    u, p = line_profile(d)
    r = np.linspace(0.0, u[-1], 400_001)
    assert np.trapezoid(d.rd(r) * 2 * np.pi * r, r) == pytest.approx(albedo, rel=2e-3)
    assert 2 * np.trapezoid(p, u) == pytest.approx(albedo, rel=2e-3)
    assert np.all(np.diff(p) <= 1e-12)               # the profile falls off from the entry


def test_a_short_mean_free_path_is_lambertian():
    sigma = 0.4e-3
    s = np.linspace(-2 * sigma, 2 * sigma, 9)
    out = stripe_radiance(Dipole(0.8, sigma / 100), s, np.full(9, 0.7), np.zeros(9), sigma)
    np.testing.assert_allclose(out, 0.8 * np.exp(-0.5 * (s / sigma) ** 2), rtol=0.02)


def _frame(material, inc, view):
    lp = laser_plate(material, incidence_deg=inc, view_deg=view)
    fr = LaserRenderer(lp.scene, lp.camera).frame(lp.camera.cam_from_world, lp.laser)
    return lp, fr.radiance.astype(np.float64)


def _bias_mm(lp, img):
    cols, _ = detect_peaks(img * 200 / img.max(), options=StripeOptions(
        method="gaussian", max_width=60, threshold=5, min_contrast=3))
    return float(np.nanmedian(lp.triangulate(cols)[:, 2])) * 1e3


def _fwhm(img):
    row = img[len(img) // 2]
    return int((row > 0.5 * row.max()).sum())


def test_translucent_plate_moves_light_without_making_it():
    lam = Material(albedo=np.array([0.9, 0.9, 0.9]))
    sss = Material(albedo=np.array([0.9, 0.9, 0.9]), brdf="subsurface", mfp=0.2e-3)
    _, a = _frame(lam, 0.0, 30.0)
    _, b = _frame(sss, 0.0, 30.0)
    # the same light leaves each row, spread over more pixels
    assert b.sum() == pytest.approx(a.sum(), rel=0.03)
    assert b.max() < 0.8 * a.max()

    def core(img):   # share of a row's light within 4 pixels of its peak
        row = img[len(img) // 2]
        c = int(np.argmax(row))
        return row[c - 4:c + 5].sum() / row.sum()

    assert core(a) > 0.99 and core(b) < 0.8


def test_the_stripe_shifts_inward_as_the_shifted_source_predicts():
    """A triangulation angle of 60 degrees split between the laser's incidence and the
    view: the peak moves by mfp sin(theta_t) along the surface (the source one mean free
    path down the refracted ray), which the scanner reads as the depth
    -mfp sin(theta_t) cos(theta_i) cos(theta_v) / sin(theta_i + theta_v)."""
    white = np.array([0.9, 0.9, 0.9])
    lam = Material(albedo=white)
    biases = {}
    for mfp in (0.3e-3, 1e-3):
        for inc in (0.0, 15.0, 30.0, 45.0):
            view = 60.0 - inc
            lp, img = _frame(Material(albedo=white, brdf="subsurface", mfp=mfp), inc, view)
            b = _bias_mm(lp, img)
            ti, tv = np.radians(inc), np.radians(view)
            sin_t = np.sin(ti) / 1.5
            want = -mfp * 1e3 * sin_t * np.cos(ti) * np.cos(tv) / np.sin(ti + tv)
            assert b == pytest.approx(want, abs=0.02 * mfp * 1e3 + 2e-3)
            biases[mfp, inc] = b
            if inc == 30.0:
                widths = biases.setdefault("fwhm", [])
                widths.append(_fwhm(img))
    for mfp in (0.3e-3, 1e-3):            # deeper (inward) with the incidence ...
        seq = [biases[mfp, inc] for inc in (0.0, 15.0, 30.0, 45.0)]
        assert all(x > y for x, y in zip(seq, seq[1:], strict=False))
    for inc in (15.0, 30.0, 45.0):        # ... and with the mean free path
        assert biases[1e-3, inc] < biases[0.3e-3, inc] < 0
    lp, img = _frame(lam, 30.0, 30.0)     # a matte plate is not biased, nor widened
    assert abs(_bias_mm(lp, img)) < 0.005
    assert _fwhm(img) < biases["fwhm"][0] < biases["fwhm"][1]
