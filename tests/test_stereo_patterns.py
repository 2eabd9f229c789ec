"""Patterns and structured-light decoding on synthetic images (no renderer)."""

import numpy as np
import pytest

from acquire.camera import Camera
from acquire.render.projector import PatternProjector, sample_bilinear
from acquire.stereo.patterns import (
    gray_code_bits,
    gray_code_patterns,
    phase_shift_patterns,
    random_dots,
)
from reconstruct.stereo.structured_light import (
    decode_gray_code,
    decode_phase,
    triangulate_columns,
    unwrap_with_gray,
)


def test_gray_code_decodes_every_pixel_exactly():
    W, H = 100, 37  # not powers of two
    pats = gray_code_patterns(W, H)
    nc, nr = gray_code_bits(W, H)
    col, row, valid = decode_gray_code(pats, n_col_bits=nc, n_row_bits=nr)
    assert valid.all()
    v, u = np.mgrid[0:H, 0:W]
    np.testing.assert_array_equal(col, u)
    np.testing.assert_array_equal(row, v)


def test_gray_code_agrees_with_opencv_decoder():
    import cv2

    W, H = 40, 20
    gc = cv2.structured_light.GrayCodePattern.create(W, H)
    _, pats = gc.generate()
    nc, nr = gray_code_bits(W, H)
    col, row, _ = decode_gray_code([p.astype(float) for p in pats], n_col_bits=nc, n_row_bits=nr)
    for x, y in [(0, 0), (7, 3), (39, 19), (21, 11)]:
        err, proj = gc.getProjPixel(list(pats), x, y)
        assert not err
        assert (col[y, x], row[y, x]) == tuple(proj)


@pytest.mark.parametrize("n_steps", [3, 4, 8])
def test_phase_shift_recovers_subpixel_column(n_steps):
    W, H, P = 64, 4, 16.0
    imgs = phase_shift_patterns(W, H, period_px=P, n_steps=n_steps)
    # camera sees a shifted, scaled copy at sub-pixel positions
    x = np.linspace(0.3, 62.7, 50)
    samples = [0.1 + 0.6 * np.interp(x, np.arange(W), im[0]) for im in imgs]
    phase, mod = decode_phase([s[None, :] for s in samples])
    gray = np.round(x).astype(int)[None, :]
    c = unwrap_with_gray(phase, gray, period_px=P)
    # linear interpolation of a sampled cosine biases the phase by < 0.05 px at P = 16
    np.testing.assert_allclose(c[0], x, atol=0.05)
    np.testing.assert_allclose(mod, 0.3, rtol=0.05)


def test_unwrap_tolerates_gray_errors_below_half_period():
    phase = np.full(5, 2 * np.pi * 3.25 / 8)
    truth = 16 + 3.25
    gray = np.array([16, 19, 22, 23, 17])
    np.testing.assert_allclose(unwrap_with_gray(phase, gray, period_px=8), truth)


def test_column_plane_triangulation_round_trip():
    rng = np.random.default_rng(1)
    cam = Camera.look_at([0.0, -0.5, 0.1], [0, 0, 0], width=64, height=48, fov_deg=40,
                         dist=(0.02, 0, 0, 0, 0))
    proj = Camera.look_at([0.15, -0.5, 0.1], [0, 0, 0], width=80, height=60, fov_deg=35,
                          dist=(-0.01, 0, 0, 0, 0))
    pts = rng.uniform(-0.05, 0.05, (200, 3))
    px, _ = cam.project(pts)
    pp, _ = proj.project(pts)
    rec = triangulate_columns(cam, px, pp, proj)
    np.testing.assert_allclose(rec, pts, atol=1e-9)


def test_random_dots_deterministic_and_density():
    a = random_dots(64, 48, rng=np.random.default_rng(3), density=0.3, dot_sigma_px=0)
    b = random_dots(64, 48, rng=np.random.default_rng(3), density=0.3, dot_sigma_px=0)
    np.testing.assert_array_equal(a, b)
    assert abs(a.mean() - 0.3) < 0.05


def test_projector_irradiance_samples_pattern_and_falls_off():
    cam = Camera.look_at([0, -2, 0], [0, 0, 0], width=9, height=7)
    pat = np.zeros((7, 9))
    pat[3, 4] = 1.0  # centre pixel only
    proj = PatternProjector(cam, pat, intensity=2.0)
    e = proj.irradiance(np.zeros((1, 3)), np.array([[0.0, -1.0, 0.0]]))
    np.testing.assert_allclose(e, [[0.5, 0.5, 0.5]])  # 2 / 2^2
    # bilinear half-way between two pixels
    np.testing.assert_allclose(sample_bilinear(pat, np.array([[4.5, 3.0], [-3.0, 3.0]])), [0.5, 0])
    d, t = proj.shadow_rays(np.zeros((1, 3)))
    np.testing.assert_allclose(d, [[0, -2, 0]])
    assert t[0] == 1.0
