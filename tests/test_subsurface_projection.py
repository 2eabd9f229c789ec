"""Projected light on subsurface materials (issue 17): the dipole's Gaussian mixture
against the dipole's own transfer function, the spread conserving light, a projected
sinusoid losing the contrast the mixture predicts, and structured light's finest Gray
code bits failing first (Gupta et al., CVPR 2011: subsurface scattering blurs the
high-frequency patterns)."""

import numpy as np
import pytest
from scipy.special import j0

from acquire.render.materials import Material
from acquire.render.projector import PatternProjector
from acquire.render.scene import RenderScene, SceneObject
from acquire.render.subsurface import Dipole, gaussian_mixture, spread_irradiance
from acquire.sensor import Sensor
from acquire.stereo.patterns import gray_code_bits, gray_code_patterns, phase_shift_patterns
from acquire.stereo.rig import RigConfig
from core.meshes import make_mesh
from reconstruct.stereo.structured_light import decode_phase, gray_bit_errors


def _mtf_exact(d: Dipole, f: float) -> float:
    """The dipole's 2-D Fourier transform at spatial frequency ``f`` (Hankel, numeric)."""
    r = np.concatenate([np.linspace(0.0, 2 * d.mfp, 4000),
                        np.geomspace(2 * d.mfp, 400 * d.mfp, 20000)])
    return float(np.trapezoid(d.rd(r) * j0(2 * np.pi * f * r) * 2 * np.pi * r, r))


def _mtf_mixture(sig, w, f: float) -> float:
    return float(np.sum(w * np.exp(-2 * np.pi ** 2 * sig ** 2 * f ** 2)))


@pytest.mark.parametrize("albedo", [0.3, 0.8, 0.95])
def test_mixture_has_the_dipoles_transfer_function(albedo):
    d = Dipole(albedo, 1e-3)
    sig, w = gaussian_mixture(d)
    assert w.sum() == pytest.approx(d.multiple, rel=1e-12)
    assert np.all(w > 0) and np.all(sig > 0)
    for f in (0.0, 20.0, 50.0, 100.0, 300.0):    # cycles per metre; the mfp is 1 mm
        assert _mtf_mixture(sig, w, f) == pytest.approx(_mtf_exact(d, f), abs=0.025 * albedo)


def test_spread_conserves_light_and_keeps_it_inside_the_mask():
    mask = np.zeros((60, 80), bool)
    mask[5:55, 5:75] = True
    sig, w = np.array([0.5, 2.0, 5.0]), np.array([0.2, 0.5, 0.3])
    E = np.full(mask.shape, 2.5)
    E[~mask] = 7.0
    out = spread_irradiance(E, mask, sig, w)
    assert np.allclose(out, E, rtol=0, atol=1e-12)       # even light: unchanged
    E2 = np.where(mask, 0.0, 7.0)
    E2[30, 40] = 1000.0                                   # a spot: spread, not lost
    out2 = spread_irradiance(E2, mask, sig, w)
    assert np.array_equal(out2[~mask], E2[~mask])
    assert out2[30, 40] < 300 and out2[30, 46] > 0.1
    # far from the edges the total is kept (the normalisation only acts at the edges)
    assert out2[mask].sum() == pytest.approx(1000.0, rel=0.02)


def _facing_plate(material, cam, distance=0.35, half=0.12):
    axis = cam.world_from_cam[:3, 2]
    right, down = cam.world_from_cam[:3, 0], cam.world_from_cam[:3, 1]
    c = cam.center + distance * axis
    V = np.array([c - half * right - half * down, c + half * right - half * down,
                  c + half * right + half * down, c - half * right + half * down])
    F = np.array([[0, 2, 1], [0, 3, 2]])
    obj = SceneObject("plate", make_mesh(V, F), material=material, object_id=0,
                      analytic={"type": "plane", "point": c, "normal": -axis})
    return RenderScene([obj], lights=[], ambient=0.0)


class _Ideal:
    def apply(self, img, rng):
        return img


def _render(material, patterns, sensor, cam, pcam, seed=0):
    from acquire.stereo.capture_sl import _render_patterns

    proj = PatternProjector(pcam, patterns[0], 0.12)
    imgs, depth = _render_patterns(_facing_plate(material, cam), cam, proj, patterns, sensor,
                                   np.random.default_rng(seed), supersample=1, ambient=0.0)
    return imgs, depth


@pytest.fixture(scope="module")
def devices():
    return RigConfig().sl_devices()


def _true_columns(cam, pcam, depth):
    m = depth > 0
    yy, xx = np.nonzero(m)
    pts = cam.unproject(np.stack([xx, yy], 1).astype(float), depth[m].astype(float))
    true = np.full(depth.shape, -1, np.int64)
    col = pcam.project(pts)[0][:, 0]
    true[yy, xx] = np.where((col >= 0) & (col < pcam.width), np.round(col), -1)
    return true, pts, col, (yy, xx)


def test_projected_sinusoid_loses_the_contrast_the_mixture_predicts(devices):
    cam, pcam = devices
    period = 16
    pats = phase_shift_patterns(pcam.width, pcam.height, period_px=period, n_steps=4, axis="x")
    albedo = np.array([0.8, 0.8, 0.8])
    matte, depth = _render(Material(albedo=albedo), pats, _Ideal(), cam, pcam)
    _, mod_m = decode_phase(matte)
    # the pattern's period on the plate, from the projector columns of the true points
    _, pts, col, _ = _true_columns(cam, pcam, depth)
    A = np.c_[pts, np.ones(len(pts))]
    grad = np.linalg.lstsq(A, col, rcond=None)[0][:3]     # projector columns per metre
    f = np.linalg.norm(grad) / period                     # cycles per metre on the plate
    h, w = depth.shape
    centre = (slice(h // 4, 3 * h // 4), slice(w // 4, 3 * w // 4))
    for mfp in (0.3e-3, 1e-3):
        mat = Material(albedo=albedo, brdf="subsurface", mfp=mfp)
        sub, _ = _render(mat, pats, _Ideal(), cam, pcam)
        _, mod_s = decode_phase(sub)
        ratio = np.median(mod_s[centre]) / np.median(mod_m[centre])
        sig, wts = gaussian_mixture(Dipole(0.8, mfp, mat.ior))
        predicted = _mtf_mixture(sig, wts, f) / 0.8
        assert predicted < 0.9                            # the effect is there
        assert ratio == pytest.approx(predicted, rel=0.15, abs=0.02)


def test_finest_gray_code_bits_fail_first_on_subsurface_materials(devices):
    cam, pcam = devices
    nc, _ = gray_code_bits(pcam.width, pcam.height)
    pats = gray_code_patterns(pcam.width, pcam.height)[: 2 * nc]
    albedo = np.array([0.7, 0.7, 0.7])
    mats = {"matte": Material(albedo=albedo),
            "marble": Material(albedo=albedo, brdf="subsurface", mfp=0.4e-3),
            "wax": Material(albedo=albedo, brdf="subsurface", mfp=2e-3)}
    contrast, rates = {}, {}
    noisy = Sensor(mono=True, full_well=3000.0, read_noise=8.0)   # a small-pixel camera
    for name, mat in mats.items():
        imgs, depth = _render(mat, pats, _Ideal(), cam, pcam)
        true, *_ = _true_columns(cam, pcam, depth)
        seen = true >= 0
        contrast[name] = np.array([np.median((np.abs(imgs[2 * k] - imgs[2 * k + 1]) / np.maximum(
            imgs[2 * k] + imgs[2 * k + 1], 1e-12))[seen]) for k in range(nc)])
        rng = np.random.default_rng(1)
        rates[name] = gray_bit_errors([noisy.apply(im, rng) for im in imgs], true, n_bits=nc)
    # a bit's contrast (pattern against inverse) falls with its frequency, more as the
    # mean free path grows; matte keeps it all
    assert np.all(contrast["matte"][:-1] > 0.99)
    for name in ("marble", "wax"):
        assert np.all(np.diff(contrast[name]) <= 1e-6)
        assert contrast[name][0] > 0.99
    assert np.all(contrast["wax"][3:] < contrast["marble"][3:])
    assert contrast["wax"][-2] < 0.1 and contrast["marble"][-2] < 0.5
    # with sensor noise the finest resolved bit fails on wax, not on matte, and the coarse
    # bits decode on both
    k = nc - 2                                            # the last bit with stable pixels
    assert rates["wax"][k] > 0.03 and rates["wax"][k] > 10 * rates["matte"][k]
    assert np.nanmax(rates["wax"][:4]) < 0.002
