"""SfM geometry without COLMAP: Sim(3) alignment, capture paths, nerfstudio export,
COLMAP camera conversions."""

import json

import numpy as np
import pytest

from acquire.camera import Camera, look_at_cam_from_world
from acquire.sfm.nerfstudio import GL_FROM_CV, read_transforms, write_transforms
from acquire.sfm.paths import (
    handheld_walk,
    hemisphere,
    interpolate_pose,
    orbit_rings,
    subframe_poses,
)
from core.frames import rotation_angle_deg
from reconstruct.evaluation.sim3 import Sim3, align_cameras, umeyama


def _random_rotation(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def test_umeyama_recovers_a_known_similarity(rng):
    R = _random_rotation(rng)
    src = rng.normal(size=(20, 3))
    dst = 3.7 * src @ R.T + [0.3, -2.0, 5.0]
    sim = umeyama(src, dst)
    assert sim.scale == pytest.approx(3.7, rel=1e-12)
    np.testing.assert_allclose(sim.R, R, atol=1e-12)
    np.testing.assert_allclose(sim.t, [0.3, -2.0, 5.0], atol=1e-12)
    np.testing.assert_allclose(sim.apply(src), dst, atol=1e-12)


def test_umeyama_never_returns_a_reflection(rng):
    src = rng.normal(size=(10, 3))
    dst = src * [1, 1, -1]  # a mirror image: the best rotation has det +1
    sim = umeyama(src, dst)
    assert np.linalg.det(sim.R) == pytest.approx(1.0)


def test_align_cameras_is_exact_on_a_similar_copy(rng):
    true = {f"im{i}": look_at_cam_from_world(rng.normal(size=3) * 2 + [0, 0, 3], [0, 0, 0])
            for i in range(8)}
    R = _random_rotation(rng)
    # the SfM frame: world_sfm = (R^T (x - t)) / s, the inverse of a similarity
    back = Sim3(0.25, R.T, -0.25 * R.T @ np.array([1.0, 2.0, 3.0]))
    est = {k: back.apply_cam_from_world(T) for k, T in list(true.items())[:6]}
    errs = align_cameras(est, true)
    assert errs.registered_fraction == pytest.approx(6 / 8)
    assert errs.rotation_deg.max() < 1e-9
    assert errs.ate < 1e-9
    assert errs.alignment.scale == pytest.approx(4.0)


def test_rotation_angle_matches_the_constructed_angle():
    for deg in (0.0, 1e-4, 0.1, 45.0, 179.9):
        a = np.radians(deg)
        R = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        assert rotation_angle_deg(R) == pytest.approx(deg, abs=1e-9)


def test_orbit_and_hemisphere_look_at_the_target():
    target = np.array([0.1, -0.2, 0.3])
    cam = Camera.look_at([1, 0, 0], [0, 0, 0], width=64, height=48, fov_deg=60)
    for poses in (orbit_rings(target, 0.5, elevations_deg=(10, 50), views_per_ring=7),
                  hemisphere(target, 0.5, 11, min_elevation_deg=15, max_elevation_deg=70)):
        for T in poses:
            c = cam.with_pose(T)
            px, z = c.project(target[None])
            np.testing.assert_allclose(px[0], [c.cx, c.cy], atol=1e-9)
            assert z[0] == pytest.approx(0.5)
    el = [np.degrees(np.arcsin((cam.with_pose(T).center - target)[2] / 0.5))
          for T in hemisphere(target, 0.5, 50, min_elevation_deg=15, max_elevation_deg=70)]
    assert 15 <= min(el) and max(el) <= 70


def test_handheld_walk_is_reproducible_and_jittered():
    a = handheld_walk([0, 0, 0], 1.0, 10, rng=np.random.default_rng(3))
    b = handheld_walk([0, 0, 0], 1.0, 10, rng=np.random.default_rng(3))
    c = handheld_walk([0, 0, 0], 1.0, 10, rng=np.random.default_rng(4))
    assert np.array_equal(a, b) and not np.allclose(a, c)
    for T in a:
        np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)


def test_subframe_poses_are_centred_on_the_frame():
    T0 = look_at_cam_from_world([1, 0, 0.5], [0, 0, 0])
    T1 = look_at_cam_from_world([0, 1, 0.5], [0, 0, 0])
    sub = subframe_poses(T0, T1, 3, shutter=0.5)
    np.testing.assert_allclose(sub[1], T0, atol=1e-12)
    np.testing.assert_allclose(interpolate_pose(T0, T1, 1.0), T1, atol=1e-12)
    # symmetric about T0: rotation angles to T0 equal
    a = rotation_angle_deg(sub[0][:3, :3] @ T0[:3, :3].T)
    b = rotation_angle_deg(sub[2][:3, :3] @ T0[:3, :3].T)
    assert a == pytest.approx(b, rel=1e-9) and a == pytest.approx(90 * 0.5 / 3, rel=1e-6)


def test_transforms_json_round_trip_and_opengl_axes(tmp_path):
    cams = [Camera(64, 48, 50.0, 51.0, 31.0, 24.5, [0.01, -0.002, 0.0, 0.0, 0.0],
                   look_at_cam_from_world(eye, [0, 0, 0]))
            for eye in ([1, 0, 0.5], [0, 1, 0.7], [-1, 0.2, 0.4])]
    write_transforms(tmp_path / "transforms.json", cams, ["a.png", "b.png", "c.png"])
    data = json.loads((tmp_path / "transforms.json").read_text())
    assert data["cx"] == 31.5 and data["fl_y"] == 51.0  # half-pixel shift, shared intrinsics
    for cam, fr in zip(cams, data["frames"], strict=False):
        M = np.asarray(fr["transform_matrix"])
        # OpenGL: the camera looks down its -z axis, y is up in the image
        look = -M[:3, 2]
        to_target = -cam.center / np.linalg.norm(cam.center)
        np.testing.assert_allclose(look, to_target, atol=1e-12)
        assert M[2, 1] > 0  # image up has a positive world-z component
    back, paths = read_transforms(tmp_path / "transforms.json")
    assert paths == ["a.png", "b.png", "c.png"]
    for a, b in zip(cams, back, strict=False):
        np.testing.assert_allclose(b.cam_from_world, a.cam_from_world, atol=1e-12)
        np.testing.assert_allclose(b.K, a.K, atol=1e-12)
        np.testing.assert_allclose(b.dist, a.dist, atol=1e-15)
    np.testing.assert_array_equal(GL_FROM_CV @ GL_FROM_CV, np.eye(4))


def test_colmap_camera_conversion_round_trip():
    import cv2  # noqa: F401
    import pycolmap

    from reconstruct.camera_files import camera_from_colmap, colmap_params_from_camera

    cam = Camera(320, 240, 300.0, 300.0, 159.5, 119.5, [0.02, 0, 0, 0, 0])
    model, params = colmap_params_from_camera(cam)
    assert model == "SIMPLE_RADIAL"
    pc = pycolmap.Camera.create_from_model_name(1, model, 300.0, 320, 240)
    pc.set_params_from_string(params)
    assert pc.principal_point_x == 160.0  # COLMAP: pixel centres at half integers
    back = camera_from_colmap(pc)
    np.testing.assert_allclose(back.K, cam.K)
    np.testing.assert_allclose(back.dist, cam.dist)
    # both models project a point to the same place (up to the half-pixel convention)
    p = np.array([[0.05, -0.03, 1.0]])
    ours, _ = cam.project(p)
    theirs = pc.img_from_cam(p)
    np.testing.assert_allclose(ours + 0.5, theirs, atol=1e-9)


def test_matcher_choice_follows_image_count_and_capture_kind():
    from reconstruct.sfm.pipeline import SfmConfig, _choose_matcher, _Input

    def pick(n, order="unknown", matcher="auto"):
        return _choose_matcher(SfmConfig(matcher=matcher), _Input(None, [f"{i}.png" for i in
                                                                       range(n)], order=order))

    assert pick(24) == "exhaustive" and pick(100) == "exhaustive"  # every pair is affordable
    assert pick(101) == "sequential"  # n^2 pairs: neighbours in file order instead
    assert pick(41, order="walk") == "sequential" and pick(40, order="walk") == "exhaustive"
    assert pick(41, order="orbit") == "exhaustive"
    assert pick(500, matcher="spatial") == "spatial"  # an explicit choice always wins
