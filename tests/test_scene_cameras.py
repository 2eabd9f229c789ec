"""Cameras from other tools' scene files (issue 32): an OpenMVS ``.mvs`` and a Meshroom
``cameras.sfm`` built by hand from known cameras read back as those cameras; malformed
files are refused with one line naming the file and the field; up beside a mesh comes
from them."""

import json
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from acquire.camera import look_at_cam_from_world
from core.io.scene_cameras import read_meshroom_sfm, read_openmvs_scene
from core.validate import InputError
from reconstruct.camera_files import read_cameras

ROOT = Path(__file__).resolve().parents[1]


def _truth(n=5, seed=0):
    """cam_from_world of ``n`` upright cameras around the origin (z up), turned by a random
    rotation R into another tool's frame; R's image of +z is the true up."""
    R = Rotation.random(random_state=seed).as_matrix()
    W = np.eye(4)
    W[:3, :3] = R
    out = []
    for k in range(n):
        a = 2 * np.pi * k / n
        T = look_at_cam_from_world([4 * np.cos(a), 4 * np.sin(a), 1.5], [0, 0, 0.5])
        out.append(T @ np.linalg.inv(W))
    return out, R @ [0.0, 0.0, 1.0]


def _s(text: str) -> bytes:
    raw = text.encode()
    return struct.pack("<Q", len(raw)) + raw


def _write_mvs(path, cams, *, K, size=(640, 480), version=6, platform_camera=True):
    """An OpenMVS scene by Interface.h: one platform, one camera (with a non-trivial pose on
    the platform when ``platform_camera``), a pose per image."""
    Rc = Rotation.from_euler("z", 90, degrees=True).as_matrix() if platform_camera \
        else np.eye(3)
    Cc = np.array([0.1, -0.2, 0.05]) if platform_camera else np.zeros(3)
    b = b"MVSI" + struct.pack("<II", version, 0)
    b += struct.pack("<Q", 1) + _s("platform0") + struct.pack("<Q", 1) + _s("cam0")
    if version > 3:
        b += _s("RGB")
    b += struct.pack("<II", *size) + struct.pack("<9d", *K.ravel())
    b += struct.pack("<9d", *Rc.ravel()) + struct.pack("<3d", *Cc)
    b += struct.pack("<Q", len(cams))
    for T in cams:  # camera R = Rc Rp, C = Rp^T Cc + Cp: solve for the platform pose
        R, C = T[:3, :3], -T[:3, :3].T @ T[:3, 3]
        Rp = Rc.T @ R
        b += struct.pack("<9d", *Rp.ravel()) + struct.pack("<3d", *(C - Rp.T @ Cc))
    b += struct.pack("<Q", len(cams) + 1)
    for i in range(len(cams) + 1):  # the last image is not calibrated (pose NO_ID)
        b += _s(f"C:\\\\photos\\\\img{i}.jpg") + (_s("") if version > 4 else b"")
        b += struct.pack("<III", 0, 0, i if i < len(cams) else 2 ** 32 - 1)
        b += struct.pack("<I", i) if version > 2 else b""
    b += struct.pack("<QQQ", 0, 0, 0)  # vertices, normals, colours: empty
    Path(path).write_bytes(b)


def _write_sfm(path, cams, *, fx=800.0, size=(640, 480), pp=(322.0, 236.0)):
    """A Meshroom cameras.sfm (version 1.2.5: focal length in mm, principal point as an
    offset from the centre, rotation written column-major as AliceVision does)."""
    w, h = size
    doc = {"version": ["1", "2", "5"], "views": [], "poses": [], "intrinsics": [{
        "intrinsicId": "77", "width": str(w), "height": str(h), "sensorWidth": "36",
        "sensorHeight": "24", "focalLength": str(fx * 36 / w), "pixelRatio": "1",
        "type": "radial3", "principalPoint": [str(pp[0] - w / 2), str(pp[1] - h / 2)],
        "distortionParams": ["0", "0", "0"]}]}
    for i, T in enumerate(cams):
        R, C = T[:3, :3], -T[:3, :3].T @ T[:3, 3]
        doc["views"].append({"viewId": str(1000 + i), "poseId": str(2000 + i),
                             "intrinsicId": "77", "path": f"/data/photos/img{i}.jpg",
                             "width": str(w), "height": str(h)})
        doc["poses"].append({"poseId": str(2000 + i), "pose": {"transform": {
            "rotation": [repr(float(x)) for x in R.ravel(order="F")],
            "center": [repr(float(x)) for x in C]}, "locked": "0"}})
    doc["views"].append({"viewId": "9", "poseId": "9", "intrinsicId": "77",
                         "path": "/data/photos/unposed.jpg"})
    Path(path).write_text(json.dumps(doc, indent=1))


K = np.array([[800.0, 0, 319.5], [0, 810.0, 241.0], [0, 0, 1]])


@pytest.mark.parametrize("version", [1, 3, 4, 5, 6])
def test_openmvs_scene_reads_back_its_cameras(tmp_path, version):
    cams, _ = _truth()
    _write_mvs(tmp_path / "scene.mvs", cams, K=K, version=version)
    got = read_openmvs_scene(tmp_path / "scene.mvs")
    assert [v.name for v in got] == [f"img{i}.jpg" for i in range(len(cams))]  # NO_ID left out
    for v, T in zip(got, cams, strict=True):
        assert np.allclose(v.cam_from_world, T, atol=1e-9)
        assert np.allclose(v.K, K) and (v.width, v.height) == (640, 480)
    cameras = read_cameras(tmp_path / "scene.mvs")
    assert cameras["img2.jpg"].fx == 800.0 and cameras["img2.jpg"].cy == 241.0


def test_meshroom_sfm_reads_back_its_cameras(tmp_path):
    cams, _ = _truth(seed=3)
    _write_sfm(tmp_path / "cameras.sfm", cams)
    got = {v.name: v for v in read_meshroom_sfm(tmp_path / "cameras.sfm")}
    assert sorted(got) == [f"img{i}.jpg" for i in range(len(cams))]  # the unposed view: out
    for i, T in enumerate(cams):
        v = got[f"img{i}.jpg"]
        assert np.allclose(v.cam_from_world, T, atol=1e-9)
        assert np.allclose(v.K, [[800, 0, 322], [0, 800, 236], [0, 0, 1]])
    # a projection through the read camera lands where the true camera puts it
    X = np.array([0.3, -0.2, 0.7])
    cam = read_cameras(tmp_path / "cameras.sfm")["img1.jpg"]
    x_true = K_project(np.array([[800, 0, 322], [0, 800, 236], [0, 0, 1.0]]), cams[1], X)
    assert np.allclose(cam.project(X[None])[0][0], x_true, atol=1e-6)


def K_project(Kmat, T, X):
    p = Kmat @ (T[:3, :3] @ X + T[:3, 3])
    return p[:2] / p[2]


def _bytes_with(path, offset, data):
    raw = bytearray(Path(path).read_bytes())
    raw[offset:offset + len(data)] = data
    Path(path).write_bytes(bytes(raw))


def test_malformed_scenes_are_refused_with_the_field(tmp_path):
    cams, _ = _truth()
    p = tmp_path / "scene.mvs"
    _write_mvs(p, cams, K=K)
    full = p.read_bytes()
    p.write_bytes(full[:200])
    with pytest.raises(InputError, match=r"scene\.mvs: platforms\[0\]"):
        read_openmvs_scene(p)
    p.write_bytes(b"MVS\0" + full[4:])
    with pytest.raises(InputError, match="header"):
        read_openmvs_scene(p)
    p.write_bytes(full[:4] + struct.pack("<I", 99) + full[8:])
    with pytest.raises(InputError, match="version"):
        read_openmvs_scene(p)
    p.write_bytes(full)  # a camera rotation scaled by 2 is not a rotation
    start = full.index(b"RGB") + 3 + 8 + 72
    _bytes_with(p, start, struct.pack("<d", 2.0))
    with pytest.raises(InputError, match=r"cameras\[0\]\.R"):
        read_openmvs_scene(p)
    s = tmp_path / "cameras.sfm"
    _write_sfm(s, cams)
    doc = json.loads(s.read_text())
    doc["poses"][2]["pose"]["transform"]["center"] = ["1", "x", "3"]
    s.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=r"cameras\.sfm: poses\[2\]\.pose\.transform\.center"):
        read_meshroom_sfm(s)
    doc["poses"][2]["pose"]["transform"]["center"] = ["1", "2", "3"]
    doc["views"][0]["intrinsicId"] = "5"
    s.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=r"views\[0\]\.intrinsicId"):
        read_meshroom_sfm(s)
    s.write_text("{not json")
    with pytest.raises(InputError, match="expected JSON"):
        read_meshroom_sfm(s)


def test_cli_exits_2_with_one_line_on_a_malformed_scene(tmp_path):
    import cv2

    photos = tmp_path / "photos"
    photos.mkdir()
    for i in range(3):
        cv2.imwrite(str(photos / f"img{i}.jpg"), np.full((48, 64, 3), 80 * i, np.uint8))
    (tmp_path / "cameras.sfm").write_text(json.dumps({"version": [1, 2, 5], "views": [],
                                                      "intrinsics": [{"intrinsicId": 1}]}))
    r = subprocess.run([sys.executable, "-m", "scanamp", "reconstruct", "sfm", str(photos),
                        "--out", str(tmp_path / "rec"), "--cameras",
                        str(tmp_path / "cameras.sfm")], capture_output=True, text=True,
                       cwd=ROOT, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
    assert r.returncode == 2, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and "cameras.sfm: intrinsics[0].width" in lines[0], r.stderr


@pytest.mark.parametrize("kind", ["mvs", "sfm"])
def test_up_comes_from_the_scene_beside_the_mesh(tmp_path, kind):
    """A facade whose largest plane is its wall, in the frame of the cameras that saw it:
    up is read from their file, whatever the mesh says."""
    from data_synth.facades import facade_mesh
    from reconstruct.surface.up import estimate_up, find_camera_model

    cams, up = _truth(seed=5)
    v, f, _ = facade_mesh(np.random.default_rng(0), rotate=False)
    R = Rotation.random(random_state=5).as_matrix()
    v = v @ R.T
    (tmp_path / "mesh.ply").write_text("")  # only its folder matters here
    if kind == "mvs":
        _write_mvs(tmp_path / "scene_dense.mvs", cams, K=K)
    else:
        _write_sfm(tmp_path / "cameras.sfm", cams)
    found = find_camera_model(tmp_path / "mesh.ply")
    assert found is not None and found.suffix == f".{kind}"
    est = estimate_up(v, f, cameras=found)
    assert est.source == "cameras"
    assert np.degrees(np.arccos(np.clip(est.up @ up, -1, 1))) < 1.0
