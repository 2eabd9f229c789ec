"""The principal point refined where the views constrain it and kept at the centre where
they do not, on small synthetic models (points seen by cameras whose lens is off-centre,
observed with noise; the model starts at the centre, as COLMAP's mapper leaves it)."""

import cv2  # noqa: F401  (before pycolmap)
import numpy as np
import pytest

from core.frames import rotation_angle_deg
from reconstruct.sfm.principal_point import refine_principal_point

W, H, F = 1200, 800, 1000.0
TRUE_PP = np.array([W / 2 + 12.0, H / 2 - 9.0])  # COLMAP's pixel convention


def _look_at(centre, target):
    z = target - centre
    z /= np.linalg.norm(z)
    x = np.cross([0.0, -1.0, 0.0], z)
    x /= np.linalg.norm(x)
    R = np.array([x, np.cross(z, x), z])
    return R, -R @ centre


def _model(tmp_path, centres, targets, rng, n_points=400, noise=0.3):
    """A COLMAP text model of ``centres`` looking at ``targets``: observations made with
    the true principal point, the model's camera at the centre, poses at the truth; then
    adjusted with the centre held (what the mapper hands over)."""
    import pycolmap

    from reconstruct.sfm.principal_point import _adjust

    pts = rng.uniform(-1.0, 1.0, size=(n_points, 3)) * [2.0, 1.5, 1.0]
    poses = [_look_at(np.asarray(c, float), np.asarray(t, float))
             for c, t in zip(centres, targets, strict=True)]
    views = []
    for R, t in poses:
        xc = pts @ R.T + t
        uv = F * xc[:, :2] / xc[:, 2:] + TRUE_PP + rng.normal(scale=noise, size=(len(pts), 2))
        ok = (xc[:, 2] > 0) & (uv[:, 0] > 0) & (uv[:, 0] < W) & (uv[:, 1] > 0) & (uv[:, 1] < H)
        views.append((uv, ok))
    seen = np.sum([ok for _, ok in views], axis=0) >= 2
    obs, lines = {}, []
    for i, ((R, t), (uv, ok)) in enumerate(zip(poses, views, strict=True), start=1):
        q = pycolmap.Rotation3d(R).quat  # x, y, z, w
        lines.append(f"{i} " + " ".join(f"{float(v):.17g}" for v in (q[3], q[0], q[1], q[2], *t))
                     + f" 1 v{i}.png")
        row = []
        for k, j in enumerate(np.nonzero(ok & seen)[0]):
            row.append(f"{uv[j, 0]:.17g} {uv[j, 1]:.17g} {j + 1}")
            obs.setdefault(j + 1, []).append(f"{i} {k}")
        lines.append(" ".join(row))
    (tmp_path / "images.txt").write_text("\n".join(lines) + "\n")
    (tmp_path / "cameras.txt").write_text(f"1 SIMPLE_RADIAL {W} {H} {F} {W / 2} {H / 2} 0\n")
    (tmp_path / "points3D.txt").write_text("".join(
        f"{p} {pts[p - 1, 0]:.17g} {pts[p - 1, 1]:.17g} {pts[p - 1, 2]:.17g} 128 128 128 0 "
        + " ".join(track) + "\n" for p, track in obs.items()))
    rec = pycolmap.Reconstruction(str(tmp_path))
    _adjust(rec, False, 1)
    return rec, poses


def _rotation_errors(rec, poses):
    """Per-view rotation error (degrees) after removing the best common rotation (the
    model's gauge): relative to view 1."""
    est = {im.image_id: im.cam_from_world().rotation.matrix() for im in rec.images.values()}
    R1e, R1t = est[1], poses[0][0]
    return np.array([rotation_angle_deg((est[i] @ R1e.T) @ (poses[i - 1][0] @ R1t.T).T)
                     for i in sorted(est) if i != 1])


def _ring(n, degrees, elevations=(0.0,)):
    """``n`` views on an arc of ``degrees`` at 6 m, at each elevation in turn (degrees)."""
    a = np.radians(np.linspace(-degrees / 2, degrees / 2, n))
    e = np.radians([elevations[k % len(elevations)] for k in range(n)])
    return [6.0 * np.array([np.sin(x) * np.cos(y), -np.sin(y), -np.cos(x) * np.cos(y)])
            for x, y in zip(a, e, strict=True)], [np.zeros(3)] * n


def test_a_spread_of_views_refines_it_to_the_truth(tmp_path, rng):
    rec, poses = _model(tmp_path, *_ring(9, 70.0, (-25.0, 0.0, 25.0)), rng)
    before = _rotation_errors(rec, poses)
    out, (d,) = refine_principal_point(rec, [1], num_threads=1, rng=np.random.default_rng(0))
    cam = out.cameras[1]
    pp = np.array([cam.principal_point_x, cam.principal_point_y])
    assert d.refined and d.axes == "xy", d.reason
    assert np.linalg.norm(pp - TRUE_PP) < 2.0  # 15 px off at the start
    assert max(d.sigma_px) < 2.0 and d.rms_px[1] < d.rms_px[0]
    after = _rotation_errors(out, poses)
    assert np.median(after) < 0.3 * np.median(before)
    # the input is left as it was
    assert rec.cameras[1].principal_point_x == W / 2


def test_parallel_views_keep_the_centre_with_the_reason(tmp_path, rng):
    centres = [np.array([x, 0.0, -6.0]) for x in np.linspace(-2.0, 2.0, 7)]
    rec, _ = _model(tmp_path, centres, [c + [0.0, 0.0, 6.0] for c in centres], rng)
    out, (d,) = refine_principal_point(rec, [1], num_threads=1)
    assert not d.refined and d.spread_deg < 1.0 and "optical axes span" in d.reason
    assert out is rec and out.cameras[1].principal_point_x == W / 2


def test_a_ring_at_one_height_refines_x_only(tmp_path, rng):
    rec, poses = _model(tmp_path, *_ring(9, 70.0), rng)
    out, (d,) = refine_principal_point(rec, [1], num_threads=1)
    cam = out.cameras[1]
    assert d.axes == "x", d.reason
    assert abs(cam.principal_point_x - TRUE_PP[0]) < 2.0 and cam.principal_point_y == H / 2


def test_an_unstable_estimate_keeps_the_centre(tmp_path, rng):
    rec, _ = _model(tmp_path, *_ring(9, 70.0, (-25.0, 0.0, 25.0)), rng)
    # halves agreeing to 1e-4 degrees is more than 0.3 px of noise on 400 points gives
    out, (d,) = refine_principal_point(rec, [1], num_threads=1, max_sigma_deg=1e-4)
    assert not d.refined and d.reason.count("above 0.0001 deg") == 2
    assert out is rec and out.cameras[1].principal_point_y == H / 2


@pytest.mark.parametrize("views", [3])
def test_too_few_views_keep_the_centre(tmp_path, rng, views):
    rec, _ = _model(tmp_path, *_ring(views, 70.0), rng)
    _, (d,) = refine_principal_point(rec, [1], num_threads=1)
    assert not d.refined and f"{views} views" in d.reason
