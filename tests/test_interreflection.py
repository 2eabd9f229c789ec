"""Inter-reflections (issue 17): structured light on a concave groove, rendered with one
bounce of indirect light. Gray-code errors appear only with the bounce, concentrate in
the concavity (near the crease), and the high-frequency patterns err less than the
low-frequency one matching the groove's scale (Gupta and Nayar's observation: a fine
pattern's indirect light is the same under the pattern and its inverse)."""

import numpy as np
import pytest

from acquire.render.materials import Material
from acquire.render.projector import PatternProjector
from acquire.stereo.capture_sl import _render_patterns
from acquire.stereo.patterns import gray_code_bits, gray_code_patterns
from acquire.stereo.rig import RigConfig
from data_synth.plates import v_groove
from reconstruct.stereo.structured_light import decode_gray_code, gray_bit_errors


class _Ideal:
    """A noiseless sensor: the effect alone."""

    def apply(self, img, rng):
        return img


@pytest.fixture(scope="module")
def groove():
    cam, pcam = RigConfig().sl_devices()
    nc, _ = gray_code_bits(pcam.width, pcam.height)
    pats = gray_code_patterns(pcam.width, pcam.height)[: 2 * nc]
    proj = PatternProjector(pcam, pats[0], 0.12)
    scene = v_groove(Material(albedo=np.array([0.95, 0.95, 0.95])), opening_deg=50.0)
    out = {}
    for bounces in (0, 1):
        imgs, depth = _render_patterns(scene, cam, proj, pats, _Ideal(),
                                       np.random.default_rng(0), supersample=2, ambient=0.0,
                                       bounces=bounces)
        out[bounces] = imgs
    m = depth > 0
    yy, xx = np.nonzero(m)
    pts = cam.unproject(np.stack([xx, yy], 1).astype(float), depth[m].astype(float))
    true = np.full(depth.shape, -1, np.int64)
    col = np.round(pcam.project(pts)[0][:, 0]).astype(np.int64)
    true[yy, xx] = np.where((col >= 0) & (col < pcam.width), col, -1)
    xw = np.full(depth.shape, np.nan)
    xw[yy, xx] = pts[:, 0]
    return out, true, xw, nc


def _wrong(imgs, true, nc):
    col, _, _ = decode_gray_code(imgs, n_col_bits=nc, n_row_bits=0, min_bit_contrast=0.0)
    return (true >= 0) & (np.abs(col - true) > 1)


def test_gray_code_errors_come_from_the_bounce_and_sit_in_the_concavity(groove):
    out, true, xw, nc = groove
    direct, bounced = _wrong(out[0], true, nc), _wrong(out[1], true, nc)
    valid = true >= 0
    assert direct[valid].mean() < 0.001                   # direct light decodes cleanly
    assert bounced[valid].mean() > 0.02                   # inter-reflections do not
    near = valid & (np.abs(xw) < 0.02)                    # within 2 cm of the crease
    far = valid & (np.abs(xw) >= 0.02)
    assert bounced[near].mean() > 3 * bounced[far].mean()


def test_fine_patterns_err_less_than_coarse_ones(groove):
    out, true, _, nc = groove
    rate = gray_bit_errors(out[1], true, n_bits=nc)
    assert np.nanmax(gray_bit_errors(out[0], true, n_bits=nc)) < 0.002
    coarse = np.nanmax(rate[:5])                          # stripes 32 px and wider
    fine = np.nanmean(rate[5:])                           # stripes 16 px and finer
    assert coarse > 3 * fine
