"""Strecha's ``.camera`` files: the convention, checked against the benchmark's own
photos; the round trip; bad files named by row; ``--cameras`` with a missing image."""

import cv2
import numpy as np
import pytest

from acquire.camera import Camera
from core.validate import InputError
from reconstruct.camera_files import read_cameras, read_strecha_camera, write_strecha_camera
from scanamp.cli import main

# fountain-P11's cameras 0004 and 0006 as the benchmark publishes them
FOUNTAIN_0004 = """2759.48 0 1520.69
0 2764.16 1006.81
0 0 1
0 0 0
0.890856 -0.0211638 -0.453793
-0.454283 -0.0449857 -0.889721
-0.00158434 0.998763 -0.0496901
-12.404 -3.81315 0.110559
3072 2048
"""
FOUNTAIN_0006 = """2759.48 0 1520.69
0 2764.16 1006.81
0 0 1
0 0 0
0.994915 -0.00462005 -0.100616
-0.100715 -0.0339759 -0.994335
0.00117536 0.999412 -0.0342684
-15.8818 -3.15083 0.0592619
3072 2048
"""
# SIFT matches (x, y in 0004, x, y in 0006; pixels, OpenCV centres) of those two photos,
# measured once with OpenCV's SIFT at full size, ratio 0.6, kept as the inliers of a
# fundamental matrix (RANSAC, 0.5 px: no camera file involved), one per 768 x 512 cell
MATCHES = np.array([
    (467.07, 259.45, 375.75, 48.50), (526.09, 641.58, 462.96, 520.12),
    (500.38, 1385.19, 437.95, 1412.06), (744.97, 1828.25, 1311.19, 1903.27),
    (947.38, 348.99, 1000.64, 224.99), (986.39, 858.45, 1095.75, 802.77),
    (871.82, 1083.04, 959.54, 1052.55), (1364.93, 1608.96, 1963.29, 1607.36),
    (2114.79, 426.41, 2200.99, 427.97), (1862.37, 965.46, 2013.13, 941.05),
    (2040.51, 1246.62, 2243.99, 1216.05), (1540.27, 1773.06, 2160.74, 1759.85),
    (2422.80, 284.01, 2459.54, 321.07), (2430.73, 696.97, 2466.22, 703.25),
    (2503.08, 1257.67, 2522.26, 1217.31), (2836.67, 1728.03, 2799.96, 1622.07)])


def _reprojection(cam_a: Camera, cam_b: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Triangulate the matches with the two cameras; reprojection error (px) per match
    (the worse view) and whether the point is in front of both."""
    def P(c):
        K = np.array([[c.fx, 0, c.cx], [0, c.fy, c.cy], [0, 0, 1]])
        return K @ c.cam_from_world[:3]

    X = cv2.triangulatePoints(P(cam_a), P(cam_b), MATCHES[:, :2].T, MATCHES[:, 2:].T)
    X = (X[:3] / X[3]).T
    err, front = np.zeros(len(X)), np.ones(len(X), bool)
    for c, x in ((cam_a, MATCHES[:, :2]), (cam_b, MATCHES[:, 2:])):
        px, z = c.project(X)
        err = np.maximum(err, np.linalg.norm(px - x, axis=1))
        front &= z > 0
    return err, front


def _other_readings(text: str) -> dict:
    """The same file read the other ways one could: R as cam_from_world, the centre as
    the translation t, both."""
    v = np.array(text.split(), float)
    K, R, C = v[:9].reshape(3, 3), v[12:21].reshape(3, 3), v[21:24]
    U, _, Vt = np.linalg.svd(R)
    R = U @ Vt
    out = {}
    for name, Rc, t in (("R cam_from_world", R, -R @ C), ("C as t", R.T, C),
                        ("R cam_from_world, C as t", R, C)):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = Rc, t
        out[name] = Camera(3072, 2048, K[0, 0], K[1, 1], K[0, 2], K[1, 2], np.zeros(5), T)
    return out


def test_the_benchmarks_photos_agree_only_under_our_reading(tmp_path):
    (tmp_path / "a.camera").write_text(FOUNTAIN_0004)
    (tmp_path / "b.camera").write_text(FOUNTAIN_0006)
    a, b = read_strecha_camera(tmp_path / "a.camera"), read_strecha_camera(tmp_path / "b.camera")
    err, front = _reprojection(a, b)
    assert front.all() and np.median(err) < 0.5 and err.max() < 1.5
    # the camera's y axis (image down) is the world's +Z: the benchmark's world is Z-down
    assert (a.cam_from_world[1, :3] @ [0, 0, 1]) > 0.99
    other_a, other_b = _other_readings(FOUNTAIN_0004), _other_readings(FOUNTAIN_0006)
    for name in other_a:
        err, front = _reprojection(other_a[name], other_b[name])
        assert np.median(err) > 20.0 or not front.all(), name


def test_round_trip_of_a_synthetic_camera(tmp_path, rng):
    from core.frames import rotation_about

    T = rotation_about([0.3, -0.5, 0.8], 1.1)
    T[:3, 3] = [0.4, -1.2, 3.5]
    cam = Camera(640, 480, 512.5, 515.25, 321.75, 236.5, np.zeros(5), T)
    write_strecha_camera(tmp_path / "v.png.camera", cam)
    back = read_cameras(tmp_path / "v.png.camera")["v.png"]
    pts = rng.normal(size=(50, 3)) + cam.center + 4 * cam.cam_from_world[2, :3]
    assert np.allclose(back.cam_from_world, cam.cam_from_world, atol=1e-12)
    assert (back.width, back.height, back.fx, back.fy, back.cx, back.cy) == \
        (640, 480, 512.5, 515.25, 321.75, 236.5)
    assert np.allclose(back.project(pts)[0], cam.project(pts)[0], atol=1e-9)
    # the file's R holds the camera's axes as columns: its third column is the view axis
    rows = (tmp_path / "v.png.camera").read_text().splitlines()
    R = np.array([r.split() for r in rows[4:7]], float)
    assert np.allclose(R[:, 2], cam.cam_from_world[2, :3])


def test_a_folder_of_camera_files_is_read_by_image_name(tmp_path):
    (tmp_path / "0004.jpg.camera").write_text(FOUNTAIN_0004)
    (tmp_path / "0006.jpg.camera").write_text(FOUNTAIN_0006)
    cams = read_cameras(tmp_path, sizes={"0004.jpg": (3072, 2048), "0006.jpg": (3072, 2048)})
    assert sorted(cams) == ["0004.jpg", "0006.jpg"]
    assert np.allclose(cams["0006.jpg"].center, [-15.8818, -3.15083, 0.0592619], atol=1e-6)
    with pytest.raises(InputError, match="0006.jpg.*1536x1024"):
        read_cameras(tmp_path, sizes={"0006.jpg": (1536, 1024)})


def _lines(text):
    return text.splitlines()


@pytest.mark.parametrize("edit, field", [
    (lambda ls: ls[:7] + ls[8:], "rows"),                                  # a missing row
    (lambda ls: ls[:1] + ["0 2764.16 abc"] + ls[2:], "K row 2"),           # not a number
    (lambda ls: ls[:4] + ["0.9 0 0.1", "0 1 0", "0 0 1"] + ls[7:], "R"),   # not a rotation
    (lambda ls: ls[:4] + ["1 0 0", "0 1 0", "0 0 -1"] + ls[7:], "R"),      # a reflection
    (lambda ls: ls[:3] + ["-0.1 0 0"] + ls[4:], "distortion"),
    (lambda ls: ["2759.48 3 1520.69"] + ls[1:], "K row 1"),                # skew
    (lambda ls: ls[:8] + ["3072.5 2048"], "image size"),
    (lambda ls: ls[:7] + ["1 2"] + ls[8:], "centre C"),
])
def test_bad_camera_files_name_the_row(tmp_path, edit, field):
    f = tmp_path / "x.jpg.camera"
    f.write_text("\n".join(edit(_lines(FOUNTAIN_0004))) + "\n")
    with pytest.raises(InputError) as e:
        read_strecha_camera(f)
    assert e.value.field == field and e.value.path == str(f)


def _photos(folder, names, size=(96, 64)):
    folder.mkdir()
    rng = np.random.default_rng(0)
    for n in names:
        cv2.imwrite(str(folder / n), rng.integers(0, 255, (size[1], size[0], 3), np.uint8))
    return folder


def test_cameras_naming_a_missing_image_is_one_line_exit_2(tmp_path, capsys):
    photos = _photos(tmp_path / "images", ["0.png", "1.png", "2.png"])
    cams = tmp_path / "cameras"
    cams.mkdir()
    for k, n in enumerate(["0.png", "1.png", "2.png", "3.png"]):
        T = np.eye(4)
        T[0, 3] = -0.1 * k
        write_strecha_camera(cams / f"{n}.camera",
                             Camera(96, 64, 80.0, 80.0, 47.5, 31.5, np.zeros(5), T))
    code = main(["reconstruct", "sfm", str(photos), "--out", str(tmp_path / "o"),
                 "--cameras", str(cams)])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert code == 2 and len(err) == 1 and str(cams) in err[0] and "3.png" in err[0]
    assert not (tmp_path / "o").exists()
    # a malformed file in the folder: the file and its row
    (cams / "3.png.camera").unlink()
    (cams / "2.png.camera").write_text("1 2 3\n")
    code = main(["reconstruct", "sfm", str(photos), "--out", str(tmp_path / "o"),
                 "--cameras", str(cams)])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert code == 2 and len(err) == 1 and "2.png.camera" in err[0] and "rows" in err[0]
    assert not (tmp_path / "o").exists()
