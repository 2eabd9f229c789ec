"""Calibration of a user's own camera or stereo pair from photos of a board.

The "photos" are rendered views of a chessboard written to plain folders (no
capture.json): the calibration must recover the cameras that rendered them.
"""

import json

import numpy as np
import pytest

from acquire.camera import Camera, look_at_cam_from_world
from acquire.render.lights import DirectionalLight
from acquire.render.renderer import render
from acquire.render.scene import RenderScene
from acquire.sensor import Sensor
from acquire.targets import ChArUcoTarget, ChessboardTarget, target_from_spec
from core.io.image import write_image
from scanamp.cli import main

BOARD = ChessboardTarget(cols=10, rows=7, square_length=0.02)
SPEC = "chessboard:10x7:0.02"
DIST = np.array([-0.12, 0.05, 0.0, 0.0, 0.0])
BASELINE = 0.06


def _poses(n=9, seed=4):
    """Board-viewing camera centres around the board, tilted 15-35 degrees, near enough
    for the board to reach the image's corners (where distortion is measured)."""
    w, h = BOARD.size_m()
    centre = np.array([w / 2, h / 2, 0.0])
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        a = 2 * np.pi * i / n
        tilt = np.radians(rng.uniform(15, 35))
        d = rng.uniform(0.28, 0.32)
        eye = centre + d * np.array([np.sin(tilt) * np.cos(a), np.sin(tilt) * np.sin(a),
                                     -np.cos(tilt)])
        look = centre + rng.uniform(-0.01, 0.01, 3) * [1, 1, 0]
        out.append(look_at_cam_from_world(eye, look, up=(0, -1, 0)))
    return out


def _shoot(cam: Camera, scene, seed: int) -> np.ndarray:
    img = render(scene, cam, supersample=2).radiance
    return Sensor(read_noise=1.0).apply(img, np.random.default_rng(seed))


@pytest.fixture(scope="module")
def photos(tmp_path_factory):
    """Nine pairs of board photos from a rig with a 6 cm baseline and radial distortion."""
    root = tmp_path_factory.mktemp("photos")
    scene = RenderScene([BOARD.scene_object("board", np.eye(4))],
                        [DirectionalLight([0.1, 0.2, -1.0], 0.8)], 0.25)
    left0 = Camera(400, 300, 330.0, 331.0, 203.0, 148.0, DIST)
    right0 = Camera(400, 300, 335.0, 335.5, 197.0, 151.0, DIST * 0.8)
    right_from_left = np.eye(4)
    right_from_left[:3, :3] = _rot_y(np.radians(2.0))
    right_from_left[:3, 3] = right_from_left[:3, :3] @ [-BASELINE, 0.0, 0.0]
    for sub in ("left", "right"):
        (root / sub).mkdir()
    half = np.eye(4)
    half[0, 3] = BASELINE / 2  # the rig's midpoint where the pose puts the camera
    for i, cfw in enumerate(_poses()):
        left = Camera(**{**_intr(left0), "cam_from_world": half @ cfw})
        right = Camera(**{**_intr(right0), "cam_from_world": right_from_left @ half @ cfw})
        write_image(root / "left" / f"l{i:02d}.png", _shoot(left, scene, i))
        write_image(root / "right" / f"r{i:02d}.png", _shoot(right, scene, 100 + i))
    return root, left0, right0, right_from_left


def _rot_y(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _intr(cam):
    return dict(width=cam.width, height=cam.height, fx=cam.fx, fy=cam.fy, cx=cam.cx, cy=cam.cy,
                dist=cam.dist)


def test_calibrate_camera_recovers_the_camera_and_feeds_sfm(photos, tmp_path):
    from reconstruct.calibration.io import read_camera_yaml
    from reconstruct.sfm.pipeline import parse_camera

    root, left0, _, _ = photos
    out = tmp_path / "camera.yaml"
    assert main(["-q", "calibrate", "camera", str(root / "left"), "--board", SPEC,
                 "--out", str(out)]) == 0
    cam = read_camera_yaml(out)
    rep = json.loads((tmp_path / "camera_report.json").read_text())
    assert rep["undetected"] == [] and len(rep["used"]) == 9
    assert rep["rms_px"] < 0.15
    assert cam.fx == pytest.approx(left0.fx, rel=0.005)
    assert cam.fy == pytest.approx(left0.fy, rel=0.005)
    assert abs(cam.cx - left0.cx) < 1.5 and abs(cam.cy - left0.cy) < 1.5
    assert cam.dist[0] == pytest.approx(DIST[0], abs=0.02)
    # the YAML is the --camera of the SfM reconstruction: OPENCV model, COLMAP's
    # half-pixel principal point
    model, params = parse_camera(str(out))
    vals = [float(v) for v in params.split(",")]
    assert model == "OPENCV" and vals[0] == pytest.approx(cam.fx)
    assert vals[2] == pytest.approx(cam.cx + 0.5)
    assert rep["colmap_camera"].startswith("OPENCV:")


def test_calibrate_stereo_recovers_the_rig_and_rectifies_rows(photos, tmp_path):
    from reconstruct.calibration.io import read_stereo_yaml

    root, left0, right0, right_from_left = photos
    out = tmp_path / "stereo.yaml"
    assert main(["-q", "calibrate", "stereo", "--left", str(root / "left" / "*.png"),
                 "--right", str(root / "right"), "--board", SPEC, "--out", str(out)]) == 0
    calib = read_stereo_yaml(out)
    rep = json.loads((tmp_path / "stereo_report.json").read_text())
    assert rep["pairs_used"] == 9
    assert calib.baseline == pytest.approx(BASELINE, rel=0.01)
    assert np.allclose(calib.R, right_from_left[:3, :3], atol=2e-3)
    assert calib.K2[0, 0] == pytest.approx(right0.fx, rel=0.005)
    # corners land on the same rectified row: the rig is usable for row-wise matching
    assert rep["epipolar_rms_px"] < 0.1
    # and the file drives the pair reconstruction
    pair = tmp_path / "pair"
    assert main(["-q", "reconstruct", "stereo", "--left", str(root / "left" / "l00.png"),
                 "--right", str(root / "right" / "r00.png"), "--calibration", str(out),
                 "--out", str(pair)]) == 0
    assert (pair / "disparity.npy").is_file()


def test_epipolar_error_grows_with_a_wrong_calibration(photos):
    from reconstruct.calibration.images import (
        calibrate_stereo_images,
        epipolar_errors,
        sorted_images,
    )
    from reconstruct.calibration.rectify import rectify
    from reconstruct.calibration.stereo import detect_pair_views

    root = photos[0]
    L, R = sorted_images(root / "left"), sorted_images(root / "right")
    calib, rep = calibrate_stereo_images(L, R, BOARD)
    from core.io.image import read_image

    views = detect_pair_views(BOARD, ((a, read_image(a), b, read_image(b))
                                      for a, b in zip(L, R, strict=True)))
    good = np.sqrt(np.mean(epipolar_errors(rectify(calib), views.common) ** 2))
    assert good == pytest.approx(rep["epipolar_rms_px"], rel=1e-6)
    # tilt the right camera by 0.2 degrees about the baseline: rows drift apart by about
    # f * 0.0035 rad ~ 1.2 px
    calib.R = calib.R @ np.array([[1, 0, 0], [0, np.cos(0.0035), -np.sin(0.0035)],
                                  [0, np.sin(0.0035), np.cos(0.0035)]])
    bad = np.sqrt(np.mean(epipolar_errors(rectify(calib), views.common) ** 2))
    assert bad > 10 * good and 0.6 < bad < 2.5


def test_wrong_board_size_exits_2_with_a_hint(photos, tmp_path, capsys):
    root = photos[0]
    code = main(["calibrate", "camera", str(root / "left"), "--board", "chessboard:9x6:0.02",
                 "--out", str(tmp_path / "c.yaml")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "counted in squares" in err[0] and "left" in err[0]
    assert not (tmp_path / "c.yaml").exists()


@pytest.mark.parametrize("argv, needle", [
    (["camera", "{root}/left", "--board", "chessboard:10by7:0.02"], "board: expected"),
    (["camera", "{root}/left", "--board", "hexboard:10x7:0.02"], "board: expected"),
    (["camera", "{root}/nowhere/*.png", "--board", "chessboard:10x7:0.02"],
     "matches no image file"),
    (["camera", "{root}", "--board", "chessboard:10x7:0.02"], "holds no image file"),
    (["stereo", "--left", "{root}/left", "--right", "{root}/left/l0[0-4].png",
      "--board", "chessboard:10x7:0.02"], "9 left images but 5 right images"),
])
def test_bad_input_exits_2_with_one_line(photos, tmp_path, capsys, argv, needle):
    root = photos[0]
    argv = [a.format(root=root) for a in argv]
    code = main(["calibrate", *argv, "--out", str(tmp_path / "x.yaml")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and needle in err[0], err


def test_board_specs():
    t = target_from_spec("charuco:7x5:0.02:0.015:DICT_4X4_50")
    assert isinstance(t, ChArUcoTarget) and t.dictionary == "DICT_4X4_50"
    assert t.square_length == 0.02 and t.marker_length == 0.015
    c = target_from_spec("Chessboard:10x7:0.03")
    assert isinstance(c, ChessboardTarget) and (c.cols, c.rows) == (10, 7)
    with pytest.raises(ValueError, match="board: expected"):
        target_from_spec("charuco:7x5:0.02")
