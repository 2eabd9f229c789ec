"""Subsurface scattering (issue 17): the dipole conserves what it is given, tends to a
Lambertian surface, and a laser stripe on a translucent plate widens and shifts inward
by the closed-form amount of the shifted-source model, growing with the mean free path
and the incidence (Godin et al. 2001 on marble)."""

import numpy as np
import pytest

from acquire.laser.sheet import LaserRenderer
from acquire.render.materials import Material
from acquire.render.subsurface import (
    Dipole,
    line_profile,
    single_scattering,
    single_scattering_share,
    stripe_radiance,
)
from data_synth.plates import laser_plate
from reconstruct.laser.stripe import StripeOptions, detect_peaks


@pytest.mark.parametrize("albedo, mfp, g", [(0.9, 1e-3, 0.8), (0.5, 3e-4, 0.0),
                                             (0.2, 5e-3, 0.5)])
def test_the_dipole_and_the_single_term_reflect_exactly_the_albedo(albedo, mfp, g):
    d = Dipole(albedo, mfp, 1.5, g)
    u, p = line_profile(d)
    r = np.linspace(0.0, u[-1], 400_001)
    assert np.trapezoid(d.rd(r) * 2 * np.pi * r, r) == pytest.approx(d.multiple, rel=2e-3)
    assert 2 * np.trapezoid(p, u) == pytest.approx(d.multiple, rel=2e-3)
    assert d.diffusion + d.single == pytest.approx(albedo, rel=1e-9)
    assert 0 < d.single < d.single_albedo * single_scattering_share(g, 1.0) < albedo
    assert np.all(np.diff(p) <= 1e-12)               # the profile falls off from the entry


@pytest.mark.parametrize("albedo, ior, g", [(0.8, 1.0001, 0.0), (0.99, 1.0001, 0.0),
                                             (0.99, 1.0001, 0.8), (0.99, 1.5, 0.0),
                                             (0.6, 1.2, 0.5), (0.3, 1.5, 0.8)])
def test_subsurface_furnace(albedo, ior, g):
    """Energy: a beam at any incidence, diffusion plus single scattering, sends back at
    most all of its light (an index-matched boundary would give 1.32 at grazing without
    the diffusion's entry weight), and broad light exactly the albedo; the local
    transport is reciprocal."""
    m = Material(albedo=np.full(3, albedo), brdf="subsurface", mfp=1e-2, ior=ior,
                 anisotropy=g)
    x, w = np.polynomial.legendre.leggauss(48)
    mu, w = 0.5 * (x + 1), 0.5 * w
    ph = np.linspace(0, 2 * np.pi, 96, endpoint=False)
    MO, PH = (a.ravel() for a in np.meshgrid(mu, ph, indexing="ij"))
    so = np.sqrt(1 - MO ** 2)
    wo = np.stack([so * np.cos(PH), so * np.sin(PH), MO], 1)
    dw = np.repeat(w, len(ph)) * (2 * np.pi / len(ph))
    share = m.subsurface_shares()[0][0]

    def local(wi, wo):   # pi f: the diffusion in the flat limit plus single scattering
        nrm = np.broadcast_to([0.0, 0.0, 1.0], wi.shape)
        return albedo * (share * m.diffusion_weight(wi[:, 2])[:, 0]
                         * m.diffusion_weight(wo[:, 2])[:, 0]
                         + m.single_scattering(wi, wo, nrm)[:, 0])

    totals = []
    for mi in np.concatenate([mu, [1e-3, 1e-2]]):
        wi = np.broadcast_to([np.sqrt(1 - mi * mi), 0.0, mi], wo.shape)
        totals.append(np.sum(local(wi, wo) * MO * dw) / np.pi)
    totals = np.array(totals)
    assert totals.max() <= 1.0 + 2e-3
    assert 2 * np.sum(totals[:len(mu)] * mu * w) == pytest.approx(albedo, rel=5e-3)
    a, b = wo[::37], wo[np.random.default_rng(0).permutation(len(wo))[:len(wo[::37])]]
    np.testing.assert_allclose(local(a, b), local(b, a), rtol=1e-9)


def test_single_scattering_is_lommel_seeliger_without_a_boundary():
    """With no refraction (index 1) and isotropic scattering, light scattered once in a
    deep medium follows the Lommel-Seeliger law, pi f = alpha / (4 (mu_i + mu_o)); its
    broad-light albedo is alpha times int int mu mu' / (mu + mu') = 0.2046; it is
    reciprocal, and forward scattering (g toward 1) sends less of it back."""
    rng = np.random.default_rng(3)
    n = np.broadcast_to([0.0, 0.0, 1.0], (200, 3))

    def hemi(k):
        v = rng.normal(size=(k, 3))
        v[:, 2] = np.abs(v[:, 2])
        return v / np.linalg.norm(v, axis=1, keepdims=True)

    wi, wo = hemi(200), hemi(200)
    f = single_scattering(wi, wo, n, g=0.0, eta=1.0)
    np.testing.assert_allclose(f, 1 / (4 * (wi[:, 2] + wo[:, 2])), rtol=1e-12)
    np.testing.assert_allclose(single_scattering(wo, wi, n, g=0.6, eta=1.5),
                               single_scattering(wi, wo, n, g=0.6, eta=1.5), rtol=1e-12)
    x, w = np.polynomial.legendre.leggauss(200)
    mu, w = 0.5 * (x + 1), 0.5 * w
    ls = np.sum(w[:, None] * w[None, :] * mu[:, None] * mu[None, :] / (mu[:, None] + mu[None, :]))
    assert single_scattering_share(0.0, 1.0) == pytest.approx(ls, rel=1e-6)
    shares = [single_scattering_share(g, 1.5) for g in (0.0, 0.5, 0.8, 0.95)]
    assert all(a > b for a, b in zip(shares, shares[1:], strict=False))
    assert single_scattering_share(0.0, 1.5) < single_scattering_share(0.0, 1.0)


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
    -mfp sin(theta_t) cos(theta_i) cos(theta_v) / sin(theta_i + theta_v). A strongly
    forward-scattering material (g = 0.99) has almost no single scattering, so its
    diffusion alone is seen."""
    white = np.array([0.9, 0.9, 0.9])
    lam = Material(albedo=white)
    biases = {}
    for mfp in (0.3e-3, 1e-3):
        for inc in (0.0, 15.0, 30.0, 45.0):
            view = 60.0 - inc
            lp, img = _frame(Material(albedo=white, brdf="subsurface", mfp=mfp,
                                      anisotropy=0.99), inc, view)
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


def test_light_scattered_once_pulls_the_peak_back_toward_the_entry():
    """Single scattering leaves where the light entered, so it is a sharp peak at the
    true stripe on top of the shifted diffusion: the less forward the scattering, the
    more light it has and the smaller the bias (measured at 45 degrees, mfp 1 mm:
    -0.371 mm at g = 0.99, -0.347 at 0.8, -0.140 isotropic), never past the entry."""
    white = np.array([0.9, 0.9, 0.9])
    bias = []
    for g in (0.99, 0.8, 0.0):
        lp, img = _frame(Material(albedo=white, brdf="subsurface", mfp=1e-3, anisotropy=g),
                         45.0, 15.0)
        bias.append(_bias_mm(lp, img))
    assert bias[0] < bias[1] < bias[2] < 0
    assert bias[2] > 0.6 * bias[0]
