"""The dense stage's fusion options for detail: agreement judged at each depth's own
uncertainty (pixels of disparity), erosion only at real edges (depth steps, wide gaps)."""

import numpy as np
import pytest

from acquire.camera import Camera


def _pair(baseline, f=500.0, w=200, h=150):
    """Two cameras side by side (rectified), looking down +z of the world."""
    cams = []
    for x in (0.0, baseline):
        pose = np.eye(4)
        pose[0, 3] = -x  # cam_from_world: the camera centre at (x, 0, 0)
        cams.append(Camera(w, h, f, f, (w - 1) / 2, (h - 1) / 2, np.zeros(5), pose))
    return cams


def test_depth_per_pixel_is_the_closed_form_of_a_rectified_pair():
    from reconstruct.mvs.fusion import depth_per_pixel

    f, b = 500.0, 0.2
    ref, other = _pair(b, f)
    rng = np.random.default_rng(0)
    z = rng.uniform(1.0, 5.0, 50)
    px = rng.uniform([0, 0], [199, 149], (50, 2))
    rays = np.column_stack([(px[:, 0] - ref.cx) / f, (px[:, 1] - ref.cy) / f, np.ones(50)])
    X = rays * z[:, None]  # the reference camera is the world frame
    # along the reference ray, one pixel of disparity in the other view is z^2 / (f b)
    np.testing.assert_allclose(depth_per_pixel(other, X, rays), z ** 2 / (f * b), rtol=1e-9)
    # and symmetric: along the other's ray, judged in the reference view
    Xo = X + [b, 0, 0]
    np.testing.assert_allclose(depth_per_pixel(ref, Xo, rays), z ** 2 / (f * b), rtol=1e-9)


def _fronto(cams, z0):
    depths = [np.full((c.height, c.width), z0, np.float32) for c in cams]
    normals = [np.broadcast_to(np.array([0, 0, -1.0], np.float32),
                               (c.height, c.width, 3)).copy() for c in cams]
    colors = [np.zeros((c.height, c.width, 3), np.uint8) for c in cams]
    return depths, normals, colors


@pytest.mark.parametrize("baseline", [0.05, 0.4])
def test_fusion_agreement_scales_with_the_pairs_disparity(baseline):
    """The same relative depth error agrees for a narrow pair and not for a wide one:
    what decides is the error in pixels of disparity, z^2 / (f b) per pixel."""
    from reconstruct.mvs.fusion import FusionOptions, fuse_points

    f, z0 = 500.0, 2.0
    cams = _pair(baseline, f)
    depths, normals, colors = _fronto(cams, z0)
    per_px = z0 ** 2 / (f * baseline)  # 0.16 m at 5 cm, 0.02 m at 40 cm
    opt = FusionOptions(edge_erosion=0, disparity_tol=1.0)
    for err_px, agrees in ((0.7, True), (1.4, False)):
        off = [depths[0], depths[1] + np.float32(err_px * per_px)]
        fused = fuse_points(cams, off, normals, colors, [[1], [0]], opt)
        # the overlap of the two views (the shift is b f / z px)
        shift = int(np.ceil(baseline * f / z0)) + 2
        covered = fused.masks[0][:, shift:].mean()
        assert (covered > 0.95) if agrees else (covered == 0.0), (err_px, covered)
    # a 5 % depth error is 0.6 px for the narrow pair (kept) and 5 px for the wide one
    off = [depths[0], depths[1] * np.float32(1.05)]
    kept = fuse_points(cams, off, normals, colors, [[1], [0]], opt).masks[0].any()
    assert kept == (baseline < 0.1)


def test_erosion_only_at_depth_steps_not_around_small_holes():
    from reconstruct.mvs.fusion import FusionOptions, depth_edges, fuse_points

    cams = _pair(0.05)
    depths, normals, colors = _fronto(cams, 2.0)
    d0 = depths[0].copy()
    d0[40:43, 60:63] = 0.0  # a 9-pixel hole in the flat surface
    d0[:, 150:] = 1.0  # a depth step: the right part is a nearer surface
    edge = depth_edges(d0, jump=0.03, hole_area=64)
    assert not depth_edges(d0, jump=0.0, hole_area=64)[:, 149:151].any()  # steps: off
    assert not edge[38:46, 58:66].any()  # the hole is not an edge ...
    assert edge[:, 149].all() and edge[:, 150].all() and not edge[:, 140].any()  # the step
    assert depth_edges(d0, jump=0.03, hole_area=0)[40:43, 60:63].all()  # every gap
    d1 = depths[1].copy()
    d1[:, 150 - 25:] = 1.0  # the other view sees the same nearer surface (b f / z = 25 px)
    opt = FusionOptions(edge_erosion=4, hole_area=64, edge_jump=0.1)
    m = fuse_points(cams, [d0, d1], normals, colors, [[1], [0]], opt).masks[0]
    assert m[39:44, 56:59].all() and m[39:44, 63:67].all()  # beside the hole: kept
    assert not m[:, 146:154].any()  # within 4 px of the step: eroded
    assert m[:, 155:190].mean() > 0.9 and m[:, 20:140].mean() > 0.9
    old = fuse_points(cams, [d0, d1], normals, colors, [[1], [0]],
                      FusionOptions(edge_erosion=4)).masks[0]
    assert not old[39:44, 56:59].any()  # the earlier erosion ate around the hole
