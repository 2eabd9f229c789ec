"""Stereo matching, disparity metrics and the calibration YAML on synthetic data."""

import numpy as np
import pytest

from core.validate import InputError
from reconstruct.calibration.io import read_stereo_yaml, write_stereo_yaml
from reconstruct.calibration.rectify import StereoCalibration, rectify, rectify_pair
from reconstruct.evaluation.disparity import disparity_metrics, nonoccluded_mask
from reconstruct.stereo.matching import (
    MatchOptions,
    depth_to_points,
    disparity_range,
    disparity_to_depth,
    lr_consistency,
    match,
)


def _texture(h, w, seed=0):
    import cv2

    rng = np.random.default_rng(seed)
    img = cv2.GaussianBlur(rng.random((h, w)).astype(np.float32), (0, 0), 1.0)
    img = (img - img.min()) / (img.max() - img.min())
    return img


def _shifted_pair(d, h=120, w=200):
    """Left/right images of a fronto-parallel plane at disparity ``d`` (closed form)."""
    import cv2

    tex = _texture(h, w + 64)
    mx, my = np.meshgrid(np.arange(w, dtype=np.float32) + 40, np.arange(h, dtype=np.float32))
    left = cv2.remap(tex, mx, my, cv2.INTER_CUBIC)
    right = cv2.remap(tex, mx + np.float32(d), my, cv2.INTER_CUBIC)  # x_r = x_l - d
    return (np.clip(left, 0, 1) * 255).astype(np.uint8), (np.clip(right, 0, 1) * 255).astype(
        np.uint8)


@pytest.mark.parametrize("d", [12.0, 17.5])
@pytest.mark.parametrize("wls,lr", [(False, False), (True, False), (False, True)])
def test_sgbm_plane_gives_closed_form_disparity(d, wls, lr):
    left, right = _shifted_pair(d)
    disp = match(left, right, MatchOptions(num_disparities=32, block_size=5, wls=wls,
                                           lr_check=lr))
    core = disp[10:-10, 50:-40]  # the right matcher (LR check) loses the right border
    assert np.isfinite(core).mean() > 0.95
    # SGBM's sub-pixel fit (parabola on 1/16 px) is biased by < 0.25 px on smooth textures
    assert abs(np.nanmedian(core) - d) < 0.25
    m = disparity_metrics(core, np.full(core.shape, d))
    assert m["bad1.0"] < 3.0


def test_metrics_hand_computed():
    gt = np.array([[10.0, 10.0, 10.0, 10.0, np.nan],
                   [5.0, 5.0, 5.0, 5.0, 5.0]])
    est = np.array([[10.9, 12.5, np.nan, 10.0, 3.0],
                    [5.0, 7.1, 5.2, np.nan, np.nan]])
    mask = np.ones_like(gt, bool)
    mask[1, 0] = False
    m = disparity_metrics(est, gt, mask=mask)
    # evaluated: row0 x0..3 (gt NaN at x4), row1 x1..4 -> 8 pixels
    # errors: .9, 2.5, nan(->nearest on row: x1=12.5 or x3=10.0: |x-2| tie -> left 12.5 -> 2.5), 0
    #         2.1, .2, nan(-> nearest x2 = 5.2 -> .2), nan(-> nearest x2 -> .2)
    assert m["n_pixels"] == 8
    assert m["invalid"] == pytest.approx(100 * 3 / 8)
    assert m["bad1.0"] == pytest.approx(100 * 5 / 8)  # 2.5, nan, 2.1, nan, nan
    assert m["bad2.0"] == pytest.approx(100 * 5 / 8)
    assert m["avgerr"] == pytest.approx((0.9 + 2.5 + 2.5 + 0 + 2.1 + 0.2 + 0.2 + 0.2) / 8)


def test_metrics_reject_empty_disparity():
    with pytest.raises(ValueError, match="disparity: empty"):
        disparity_metrics(np.full((3, 3), np.nan), np.ones((3, 3)))


def test_nonoccluded_mask_and_lr_consistency():
    # a foreground strip (d = 8) in front of a background (d = 2): background pixels just
    # left of the strip in the left view are hidden in the right view.
    W = 40
    gl = np.full((1, W), 2.0)
    gl[0, 20:30] = 8.0
    gr = np.full((1, W), 2.0)
    gr[0, 12:22] = 8.0  # strip moves left by 8 in the right view
    m = nonoccluded_mask(gl, gr)
    assert m[0, 20:30].all()  # the strip is seen by both
    assert not m[0, 14:20].any()  # background there maps into the strip in the right view
    assert m[0, 2:14].all() and m[0, 30:].all()
    np.testing.assert_array_equal(lr_consistency(gl, gr), m)


def _calib():
    K = np.array([[300.0, 0, 159.5], [0, 300.0, 119.5], [0, 0, 1]])
    a = np.radians(3.0)
    R = np.array([[np.cos(a), 0, -np.sin(a)], [0, 1, 0], [np.sin(a), 0, np.cos(a)]])
    return StereoCalibration(K, [0.05, -0.01, 0, 0, 0], K * [[1.01], [1.01], [1]],
                             [-0.02, 0, 0.001, 0, 0], R, [-0.08, 0.001, 0.002], (320, 240),
                             rms=0.2)


def test_yaml_round_trip(tmp_path):
    c = _calib()
    p = write_stereo_yaml(tmp_path / "stereo.yaml", c)
    c2 = read_stereo_yaml(p)
    for k in ("K1", "D1", "K2", "D2", "R", "T"):
        np.testing.assert_allclose(getattr(c2, k), getattr(c, k), rtol=0, atol=1e-12)
    assert c2.image_size == (320, 240) and c2.rms == pytest.approx(0.2)


def test_yaml_missing_matrix_names_file_and_key(tmp_path):
    c = _calib()
    p = write_stereo_yaml(tmp_path / "stereo.yaml", c)
    text = p.read_text()
    start = text.index("K2:")
    end = text.index("D2:")
    p.write_text(text[:start] + text[end:])
    with pytest.raises(InputError, match=r"stereo.yaml: K2: missing"):
        read_stereo_yaml(p)


def test_yaml_reads_opencv_sample_names_m1_m2(tmp_path):
    c = _calib()
    p = write_stereo_yaml(tmp_path / "stereo.yaml", c)
    p.write_text(p.read_text().replace("K1:", "M1:").replace("K2:", "M2:"))
    c2 = read_stereo_yaml(p)
    np.testing.assert_allclose(c2.K2, c.K2, rtol=0, atol=1e-12)


def test_camera_yaml_round_trip_and_bad_key(tmp_path):
    from acquire.camera import Camera
    from reconstruct.calibration.io import read_camera_yaml, write_camera_yaml

    cam = Camera(320, 240, 301.5, 300.25, 160.5, 119.0, np.array([-0.1, 0.02, 1e-3, -2e-3, 0]))
    p = write_camera_yaml(tmp_path / "camera.yaml", cam, rms=0.12)
    back = read_camera_yaml(p)
    np.testing.assert_allclose(back.K, cam.K, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.dist, cam.dist, rtol=0, atol=1e-15)
    assert (back.width, back.height) == (320, 240)
    p.write_text(p.read_text().replace("image_height", "height"))
    with pytest.raises(InputError, match=r"camera.yaml: image_height: missing"):
        read_camera_yaml(p)


@pytest.mark.parametrize("dtype, scale, stored, want", [
    (np.uint16, None, 256 * 37 + 128, 37.5),     # KITTI: value / 256
    (np.uint8, None, 75, 75.0),                  # Middlebury 2001-2006 full size
    (np.uint8, 3.0, 75, 25.0),                   # a reduced size that scales by 3
])
def test_png_ground_truth_disparity_scales_and_zero_is_unknown(tmp_path, dtype, scale, stored,
                                                               want):
    import cv2

    from reconstruct.stereo.pair import read_disparity

    img = np.full((4, 5), stored, dtype)
    img[0, 0] = 0
    cv2.imwrite(str(tmp_path / "gt.png"), img)
    g = read_disparity(tmp_path / "gt.png", scale=scale)
    assert np.isnan(g[0, 0]) and np.isnan(g).sum() == 1
    assert g[1, 1] == want


def test_rectified_geometry_triangulates_true_points():
    """Project points with the raw cameras, rectify the pixels, triangulate: exact."""
    import cv2

    c = _calib()
    left, right = c.cameras()
    rect = rectify(c)
    rng = np.random.default_rng(0)
    pts = rng.uniform([-0.1, -0.08, 0.6], [0.1, 0.08, 0.9], (100, 3))
    pl, _ = left.project(pts)
    pr, _ = right.project(pts)
    ul = cv2.undistortPoints(pl[:, None], c.K1, c.D1, R=rect.R1, P=rect.P1)[:, 0]
    ur = cv2.undistortPoints(pr[:, None], c.K2, c.D2, R=rect.R2, P=rect.P2)[:, 0]
    assert np.abs(ul[:, 1] - ur[:, 1]).max() < 1e-3  # rows aligned
    disp = ul[:, 0] - ur[:, 0]
    z = rect.focal * rect.baseline / disp
    cam = rect.left_camera()
    rec = cam.unproject(ul, z)
    np.testing.assert_allclose(rec, pts, atol=1e-5)
    # the dense path: a depth map on the rectified grid gives the same points
    depth = np.zeros((240, 320), np.float32)
    iu = np.round(ul).astype(int)
    depth[iu[:, 1], iu[:, 0]] = z
    P, px = depth_to_points(depth, cam)
    assert len(P) == len(np.unique(iu, axis=0))
    assert disparity_to_depth(np.array([[np.nan, 0.0]]), rect).tolist() == [[0.0, 0.0]]
    lo, num = disparity_range(rect, 0.6, 0.9)
    assert lo <= disp.min() and lo + num >= disp.max() and num % 16 == 0


def test_rectify_pair_rejects_other_size():
    rect = rectify(_calib())
    with pytest.raises(ValueError, match="right: expected an image of 320x240"):
        rectify_pair(np.zeros((240, 320), np.uint8), np.zeros((200, 320), np.uint8), rect)


@pytest.mark.parametrize("lr", [False, True])
def test_shifted_search_and_padding_match_the_left_border(lr):
    """The right image is shifted by min_disparity and the pair padded by num_disparities:
    columns SGBM leaves unmatched (x < min + num) get their disparity too."""
    d = 21.25
    left, right = _shifted_pair(d)
    opts = MatchOptions(min_disparity=16, num_disparities=16, lr_check=lr)
    disp = match(left, right, opts)
    # x < d has no match in the right image; beyond, everything (LR: but the right border)
    core = disp[10:-10, 26:-30]
    assert np.isfinite(core).mean() > 0.97
    assert abs(np.nanmedian(core) - d) < 0.25
    bare = match(left, right, MatchOptions(min_disparity=16, num_disparities=16, pad=False))
    assert not np.isfinite(bare[:, :16]).any()  # SGBM's own unmatched border
    if not lr:  # the padding only adds columns
        ok = np.isfinite(bare[10:-10, 40:-10]) & np.isfinite(disp[10:-10, 40:-10])
        assert np.median(np.abs(bare[10:-10, 40:-10] - disp[10:-10, 40:-10])[ok]) == 0.0


def test_region_of_interest_matches_only_the_lit_part_identically():
    """On a dark background, matching the bounding box of the lit pixels gives the same
    disparities as matching the whole image."""
    left, right = _shifted_pair(14.0, h=120, w=260)
    left, right = left // 2 + 60, right // 2 + 60  # lit texture, 60..187 DN
    dark = np.zeros((160, 300), np.uint8)
    L, R = dark.copy(), dark.copy()
    L[20:140, 20:280] = left
    R[20:140, 20:280] = right
    full = match(L, R, MatchOptions(min_disparity=8, num_disparities=16, roi_min_intensity=0))
    roi = match(L, R, MatchOptions(min_disparity=8, num_disparities=16, roi_min_intensity=8))
    core = (slice(30, 130), slice(50, 270))
    assert np.isfinite(roi[core]).mean() > 0.97
    np.testing.assert_allclose(roi[core], full[core], atol=0.0625, equal_nan=True)
    assert abs(np.nanmedian(roi[core]) - 14.0) < 0.25


def test_depth_error_follows_the_triangulation_law():
    """sigma_z = z^2 / (f b) * sigma_d to first order, and zero for a perfect match."""
    from types import SimpleNamespace

    from reconstruct.stereo.scoring import depth_errors as _depth_errors

    rect = SimpleNamespace(focal=500.0, baseline=0.08)
    z = 0.4
    gt = np.full((20, 30), rect.focal * rect.baseline / z)   # 100 px at 0.4 m
    mask = np.ones(gt.shape, bool)
    assert _depth_errors(gt.copy(), gt, mask, rect)["depth_rms_m"] == 0.0
    delta = 0.05
    e = _depth_errors(gt + delta, gt, mask, rect)
    law = z ** 2 / (rect.focal * rect.baseline) * delta
    assert e["depth_rms_m"] == pytest.approx(law, rel=1e-3)
    wide = SimpleNamespace(focal=500.0, baseline=0.16)        # same z, twice the baseline
    gt2 = np.full(gt.shape, wide.focal * wide.baseline / z)
    assert _depth_errors(gt2 + delta, gt2, mask, wide)["depth_rms_m"] == pytest.approx(law / 2,
                                                                                     rel=1e-3)
