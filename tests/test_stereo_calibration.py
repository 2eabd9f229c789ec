"""Stereo and turntable calibration on exact synthetic corner projections (no rendering)."""

import numpy as np
import pytest

from acquire.camera import Camera
from acquire.targets import ChArUcoTarget
from reconstruct.calibration.camera import calibrate_camera_points
from reconstruct.calibration.rectify import StereoCalibration
from reconstruct.calibration.stereo import (
    calibrate_pair,
    calibrate_turntable_mount,
    world_from_cam_at,
)


def _rot(axis, a):
    import cv2

    return cv2.Rodrigues(np.asarray(axis, float) * a)[0]


def _board_views(n, rng):
    """Board poses (cam_from_target) in front of a camera at 0.4-0.5 m, tilted."""
    out = []
    for _ in range(n):
        T = np.eye(4)
        T[:3, :3] = _rot([1, 0, 0], rng.uniform(-0.5, 0.5)) @ _rot([0, 1, 0],
                                                                    rng.uniform(-0.5, 0.5))
        c = np.array([rng.uniform(-0.08, 0.08), rng.uniform(-0.06, 0.06), rng.uniform(0.4, 0.5)])
        T[:3, 3] = c - T[:3, :3] @ np.array([0.09, 0.06, 0.0])
        out.append(T)
    return out


def _cams():
    left = Camera(640, 480, 690.0, 688.0, 322.0, 237.0, np.array([0.02, -0.01, 0, 0, 0]))
    rfl = np.eye(4)
    rfl[:3, :3] = _rot([0, 1, 0], np.radians(-8))
    rfl[:3, 3] = [-0.08, 0.001, 0.005]
    right = Camera(640, 480, 695.0, 694.0, 318.0, 241.0, np.array([-0.015, 0.005, 0, 0, 0]),
                   rfl)
    return left, right


def test_pair_calibration_recovers_exact_projections():
    rng = np.random.default_rng(0)
    P = ChArUcoTarget(squares_x=7, squares_y=5, square_length=0.03,
                      marker_length=0.022).corner_points()
    left, right = _cams()
    obj, pl, pr, common = [], [], [], []
    for T in _board_views(8, rng):
        X = P @ T[:3, :3].T + T[:3, 3]  # left camera frame = world here
        a, _ = left.project(X)
        b, _ = right.project(X)
        obj.append(P)
        pl.append(a)
        pr.append(b)
        common.append((P, a, b))
    calib, rep = calibrate_pair(obj, pl, obj, pr, common, (640, 480))
    true = StereoCalibration.from_cameras(left, right)
    assert rep["rms_stereo"] < 1e-3
    np.testing.assert_allclose(calib.K1, true.K1, atol=1e-3)
    np.testing.assert_allclose(calib.K2, true.K2, atol=1e-3)
    np.testing.assert_allclose(calib.T, true.T, atol=1e-6)  # float32 corners: ~0.2 um
    np.testing.assert_allclose(calib.R, true.R, atol=1e-6)
    # the shared single-camera entry (also used by the laser scanner) agrees
    single = calibrate_camera_points(obj, pl, (640, 480), dist_model="k1k2")
    np.testing.assert_allclose(single.camera.K, true.K1, atol=1e-3)
    with pytest.raises(ValueError, match="camera 1: expected the target in at least 3 views"):
        calibrate_pair(obj[:2], pl[:2], obj, pr, common, (640, 480))


def test_mount_fixes_the_turntable_frame():
    """Board mounted at a known place on the platter, seen at several stage angles:
    PnP over all views recovers cam_from_table exactly, origin and heading included."""
    P = ChArUcoTarget(squares_x=7, squares_y=5, square_length=0.03,
                      marker_length=0.022).corner_points()
    cam = Camera.look_at([0.0, -0.40, 0.25], [0.0, 0.0, 0.06])  # world = turntable frame
    mount = np.eye(4)  # facing the camera, centred near the axis, turned a little
    mount[:3, :3] = cam.world_from_cam[:3, :3] @ _rot([0.3, 1, 0.2], 0.2)
    mount[:3, 3] = [0.01, 0.02, 0.06] - mount[:3, :3] @ [0.09, 0.06, 0.0]
    angles = [-40.0, -20.0, 0.0, 20.0, 40.0]
    obj, px = [], []
    for a in angles:
        T = np.linalg.inv(world_from_cam_at(np.eye(4), a)) @ mount  # Rz(a) @ mount
        q, z = cam.project(P @ T[:3, :3].T + T[:3, 3])
        assert (z > 0).all() and (q >= 0).all() and (q[:, 0] < 640).all() and (q[:, 1] < 480).all()
        obj.append(P)
        px.append(q)
    table_from_cam, rep = calibrate_turntable_mount(obj, px, angles, mount, cam.K, cam.dist)
    assert rep["rms_px"] < 1e-6 and rep["method"] == "mount"
    np.testing.assert_allclose(table_from_cam, cam.world_from_cam, atol=1e-8)
    # a point seen at stage angle 90 maps back to its stage-0 position
    p0 = np.array([0.05, 0.02, 0.1])
    c, s = np.cos(np.radians(90)), np.sin(np.radians(90))
    p90 = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ p0
    x_cam = cam.cam_from_world[:3, :3] @ p90 + cam.cam_from_world[:3, 3]
    W = world_from_cam_at(table_from_cam, 90.0)
    np.testing.assert_allclose(W[:3, :3] @ x_cam + W[:3, 3], p0, atol=1e-9)
