import cv2
import numpy as np
import pytest

from acquire.camera import Camera

DISTS = [np.zeros(5), np.array([-0.28, 0.09, 0.001, -0.0015, -0.01]),
         np.array([0.12, -0.05, -0.002, 0.001, 0.02])]


def _camera(dist, rng):
    rvec = rng.normal(size=3) * 0.3
    R, _ = cv2.Rodrigues(rvec)
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = [0.05, -0.02, 0.6]
    return Camera(640, 480, 612.3, 608.9, 318.7, 241.2, dist, T)


@pytest.mark.parametrize("dist", DISTS)
def test_project_matches_opencv(dist, rng):
    cam = _camera(dist, rng)
    pts = rng.uniform(-0.15, 0.15, size=(500, 3))
    ours, z = cam.project(pts)
    rvec, _ = cv2.Rodrigues(cam.cam_from_world[:3, :3])
    ref, _ = cv2.projectPoints(pts, rvec, cam.cam_from_world[:3, 3], cam.K, dist)
    np.testing.assert_allclose(ours, ref[:, 0], atol=1e-6)
    assert np.all(z > 0)


@pytest.mark.parametrize("dist", DISTS)
def test_undistort_matches_opencv_and_round_trips(dist, rng):
    cam = _camera(dist, rng)
    px = np.stack([rng.uniform(0, 639, 400), rng.uniform(0, 479, 400)], 1)
    ideal = cam.undistort_pixels(px)
    ref = cv2.undistortPointsIter(px[:, None], cam.K, dist, None, cam.K,
                                  (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14))
    np.testing.assert_allclose(ideal, ref[:, 0], atol=1e-6)
    # project(unproject(px, d)) == px to 1e-6 px
    depth = rng.uniform(0.3, 2.0, len(px))
    back, z = cam.project(cam.unproject(px, depth))
    np.testing.assert_allclose(back, px, atol=1e-6)
    np.testing.assert_allclose(z, depth, rtol=1e-12)


def test_rays_scaled_to_zdepth(rng):
    cam = _camera(DISTS[1], rng)
    px = np.array([[10.0, 20.0], [600.0, 400.0]])
    o, d = cam.rays(px)
    p = o + 0.8 * d
    np.testing.assert_allclose(cam.to_camera(p)[:, 2], 0.8, rtol=1e-12)
    np.testing.assert_allclose(cam.project(p)[0], px, atol=1e-6)


def test_look_at_and_validation():
    cam = Camera.look_at([1, 0, 0.5], [0, 0, 0.5], width=100, height=80, fov_deg=90)
    px, z = cam.project([[0, 0, 0.5], [0, 0, 0.6]])
    assert z[0] == pytest.approx(1.0)
    assert px[1, 1] < px[0, 1]  # world up is image up (smaller v)
    assert cam.fx == pytest.approx(50.0)
    with pytest.raises(ValueError, match="width"):
        Camera(0, 10, 1, 1, 0, 0)
    with pytest.raises(ValueError, match="dist"):
        Camera(10, 10, 1, 1, 0, 0, dist=[0, 0])
    with pytest.raises(ValueError, match="cam_from_world"):
        Camera(10, 10, 1, 1, 0, 0, cam_from_world=np.diag([1, 1, -1, 1.0]))
    assert Camera.from_dict(cam.to_dict()).to_dict() == cam.to_dict()
