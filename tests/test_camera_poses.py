"""Cameras against reference cameras: the robust Sim(3) fit, per-view errors recovered
exactly, the CLI (`scanamp evaluate REC --poses-reference CAMERAS`), bad input."""

import json

import numpy as np
import pytest

from acquire.camera import Camera
from core.frames import rotation_about
from reconstruct.camera_files import write_strecha_camera
from reconstruct.evaluation.camera_poses import compare_cameras
from reconstruct.evaluation.sim3 import Sim3, robust_umeyama
from scanamp.cli import main


def _ring(n=8, f=2000.0):
    """Cameras on a 6 m arc looking at the origin (the Strecha sets' kind of spread)."""
    out = {}
    for k in range(n):
        a = np.radians(-40 + 80 * k / (n - 1))
        c = 6.0 * np.array([np.sin(a), 0.0, -np.cos(a)])
        T = rotation_about([0, 1, 0], -a)
        T[:3, 3] = -T[:3, :3] @ c
        out[f"{k:04d}.jpg"] = Camera(3072, 2048, f, f, 1535.5, 1023.5, np.zeros(5), T)
    return out


def test_robust_fit_ignores_a_third_of_the_points_wrong(rng):
    p = rng.normal(size=(12, 3))
    sim = Sim3(0.5, rotation_about([1, 2, 3], 0.7)[:3, :3], np.array([1.0, -2.0, 0.5]))
    q = sim.apply(p)
    q[:4] += rng.normal(size=(4, 3))  # four wrong
    fit, inl = robust_umeyama(p, q)
    assert inl.tolist() == [False] * 4 + [True] * 8
    assert np.isclose(fit.scale, 0.5) and np.allclose(fit.R, sim.R) and np.allclose(fit.t, sim.t)


def test_per_view_errors_are_recovered_exactly():
    ref = _ring()
    gauge = Sim3(0.3, rotation_about([0.2, 1, 0.1], 0.9)[:3, :3], np.array([2.0, 1.0, -3.0]))
    inv = Sim3(1 / gauge.scale, gauge.R.T, -gauge.R.T @ gauge.t / gauge.scale)
    est = {n: c.with_pose(inv.apply_cam_from_world(c.cam_from_world)) for n, c in ref.items()}
    # view 2 turned by 0.2 degrees about its own axis, view 5 moved 30 mm, view 6's
    # intrinsics off by 1 % and (3, 4) px
    T = est["0002.jpg"].cam_from_world.copy()
    T[:3] = rotation_about([0, 0, 1], np.radians(0.2))[:3, :3] @ T[:3]
    est["0002.jpg"] = est["0002.jpg"].with_pose(T)
    T = est["0005.jpg"].cam_from_world.copy()
    T[:3, 3] -= T[:3, :3] @ (inv.scale * np.array([0.03, 0.0, 0.0]))
    est["0005.jpg"] = est["0005.jpg"].with_pose(T)
    c = est["0006.jpg"]
    est["0006.jpg"] = Camera(c.width, c.height, 1.01 * c.fx, 1.01 * c.fy, c.cx + 3, c.cy + 4,
                             c.dist, c.cam_from_world)
    del est["0007.jpg"]
    err = compare_cameras(est, ref)
    r = dict(zip(err.names, err.rotation_deg, strict=True))
    cerr = dict(zip(err.names, err.centre_error, strict=True))
    assert np.isclose(r["0002.jpg"], 0.2, atol=1e-9)
    assert max(v for n, v in r.items() if n != "0002.jpg") < 1e-9
    # the moved view is the fit's only outlier; its error is the whole 30 mm
    assert err.inliers.tolist() == [n != "0005.jpg" for n in err.names]
    assert np.isclose(cerr["0005.jpg"], 0.03, atol=1e-9)
    assert max(v for n, v in cerr.items() if n != "0005.jpg") < 1e-9
    i = err.names.index("0006.jpg")
    assert np.isclose(err.focal_error[i], 0.01) and np.isclose(err.principal_point_error_px[i], 5)
    assert err.missing == ["0007.jpg"]
    extent = max(np.linalg.norm(a.center - b.center) for a in ref.values() for b in ref.values())
    assert np.isclose(err.extent, extent)
    s = err.summary()
    assert np.isclose(s["centre_error_fraction_of_extent"]["max"], 0.03 / extent)


def _write(folder, cams):
    folder.mkdir()
    for n, c in cams.items():
        write_strecha_camera(folder / f"{n}.camera", c)
    return folder


def test_evaluate_cli_compares_cameras(tmp_path, capsys):
    ref = _write(tmp_path / "ref", _ring())
    cams = _ring()
    c = cams["0003.jpg"]
    T = c.cam_from_world.copy()
    T[:3] = rotation_about([1, 0, 0], np.radians(0.5))[:3, :3] @ T[:3]
    cams["0003.jpg"] = c.with_pose(T)
    est = _write(tmp_path / "est", cams)
    code = main(["evaluate", str(est), "--poses-reference", str(ref), "--json",
                 str(tmp_path / "e.json")])
    out = capsys.readouterr().out
    assert code == 0 and "0003.jpg" in out and "0.5000" in out
    data = json.loads((tmp_path / "e.json").read_text())
    rot = {v["image"]: v["rotation_error_deg"] for v in data["views"]}
    assert np.isclose(rot["0003.jpg"], 0.5, atol=1e-6)


@pytest.mark.parametrize("bad, field", [("1 2 3\n", "rows"), (None, "R")])
def test_evaluate_cli_bad_reference_is_one_line_exit_2(tmp_path, capsys, bad, field):
    ref = _write(tmp_path / "ref", _ring())
    est = _write(tmp_path / "est", _ring())
    f = ref / "0004.jpg.camera"
    if bad is None:  # a rotation row scaled: not a rotation
        rows = f.read_text().splitlines()
        rows[4] = " ".join(str(2 * float(x)) for x in rows[4].split())
        bad = "\n".join(rows) + "\n"
    f.write_text(bad)
    code = main(["evaluate", str(est), "--poses-reference", str(ref), "--json",
                 str(tmp_path / "e.json")])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert code == 2 and len(err) == 1 and "0004.jpg.camera" in err[0] and field in err[0]
    assert not (tmp_path / "e.json").exists()


def test_the_joint_fit_is_free_of_a_line_of_cameras_slack(rng):
    """Cameras along a line: millimetres of centre noise leave the centres' Sim(3) loose
    about that line; the joint fit of centres and orientations does not inherit it, and
    the relative rotations (no gauge) are exact."""
    ref = {}
    for k, x in enumerate(np.linspace(-8.0, 8.0, 8)):
        T = rotation_about([0, 1, 0], 0.05 * k)
        T[:3, 3] = -T[:3, :3] @ np.array([x, 0.01 * k % 0.03, -6.0])
        ref[f"{k}.jpg"] = Camera(3072, 2048, 2700.0, 2700.0, 1535.5, 1023.5, np.zeros(5), T)
    est = {}
    for n, c in ref.items():  # the same orientations, the centres 3 mm off
        T = c.cam_from_world.copy()
        T[:3, 3] -= T[:3, :3] @ rng.normal(scale=0.003, size=3)
        est[n] = c.with_pose(T)
    err = compare_cameras(est, ref)
    assert err.rotation_deg_joint.max() < 1e-6 and err.relative_rotation_deg.max() < 1e-6
    assert np.median(err.rotation_deg) > 0.01  # the loose gauge's share
    # the centres still count: the joint fit's centre errors are the noise's size
    assert np.median(err.centre_error_joint) < 0.01


def test_a_rotation_in_every_cameras_frame_counts_against_the_centres():
    """What a wrong principal point does: every camera turned by the same angle in its
    own frame. Against the centres it is the whole error; where the centres fix the gauge
    (a ring) the joint fit keeps it, and the relative rotations (no gauge) keep it too."""
    ref = _ring()
    turn = rotation_about([1, 0, 0], np.radians(0.5))[:3, :3]
    est = {}
    for n, c in ref.items():
        T = c.cam_from_world.copy()
        R = turn @ T[:3, :3]
        T[:3, 3] = -R @ c.center
        T[:3, :3] = R
        est[n] = c.with_pose(T)
    err = compare_cameras(est, ref)
    assert np.allclose(err.rotation_deg, 0.5) and err.centre_error.max() < 1e-9
    assert np.median(err.rotation_deg_joint) > 0.4
    assert np.median(err.relative_rotation_deg) > 0.1
