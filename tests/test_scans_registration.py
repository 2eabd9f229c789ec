"""Registering range scans with no initial pose (reconstruct.registration.multiway and
friends) on generated scans: a bumpy blob ray-cast from free viewpoints, seeded noise."""

import numpy as np
import pytest

from core.frames import axis_angle_matrix, rotation_angle_deg
from core.io.range import RangeGrid
from reconstruct.evaluation.scan_poses import compare_scan_poses
from reconstruct.registration import (
    MultiwayOptions,
    Oriented,
    refine_scans,
    register_scans,
    verify_pair,
)
from reconstruct.scans import scan_from_grid


def _blob(seed_shape=0, radius=0.05):
    """A closed, bumpy, asymmetric surface (open3d mesh) about the origin."""
    import open3d as o3d

    m = o3d.geometry.TriangleMesh.create_sphere(radius=1.0, resolution=60)
    v = np.asarray(m.vertices)
    x, y, z = v.T
    if seed_shape == 0:
        r = 1 + 0.22 * np.sin(3 * x + 1) * np.cos(2 * y) + 0.15 * np.sin(5 * z + 0.5) \
            + 0.1 * np.cos(4 * x * y + 2 * z)
        v = v * r[:, None] * [1.3, 1.0, 0.8]
    else:  # another object: a flat, ridged slab
        v = v * [1.4, 1.2, 0.35] + np.stack([0 * x, 0 * y, 0.15 * np.sin(7 * x)], 1)
    m.vertices = o3d.utility.Vector3dVector(radius * v)
    return m


def _scan(mesh, eye, name, rng, *, size=(96, 72), fov=28.0, noise=2e-5):
    """A perspective range image of ``mesh`` from ``eye`` looking at the origin, in the
    scanner's OpenCV frame (origin at the scanner, +z forward); returns (scan, model_from_scan)."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    eye = np.asarray(eye, float)
    fwd = -eye / np.linalg.norm(eye)
    right = np.cross(fwd, [0, 0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    R = np.stack([right, down, fwd], 1)          # model_from_scan rotation
    w, h = size
    f = 0.5 * w / np.tan(np.radians(fov / 2))
    r, c = np.mgrid[0:h, 0:w]
    d = np.stack([(c - w / 2) / f, (r - h / 2) / f, np.ones((h, w))], -1).reshape(-1, 3)
    rays = np.hstack([np.tile(eye, (len(d), 1)), d @ R.T]).astype(np.float32)
    t = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy().astype(float)
    ok = np.isfinite(t)
    depth = t[ok] * (1 + noise * rng.standard_normal(ok.sum()) / 0.3)
    pts = d[ok] * depth[:, None]
    index = np.full(h * w, -1)
    index[ok] = np.arange(ok.sum())
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, eye
    return scan_from_grid(RangeGrid(pts, index.reshape(h, w)), name=name), T


def _views(n, dist=0.3):
    out = []
    for k in range(n):
        az = 2 * np.pi * k / n
        el = np.radians(25.0 if k % 2 else -10.0)
        out.append(dist * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az),
                                    np.sin(el)]))
    return out


@pytest.fixture(scope="module")
def blob_set():
    rng = np.random.default_rng(7)
    mesh = _blob()
    scans, truth = [], {}
    for k, eye in enumerate(_views(8)):
        s, T = _scan(mesh, eye, f"scan_{k:02d}", rng)
        scans.append(s)
        truth[s.name] = T
    foreign, _ = _scan(_blob(1), [0.2, -0.2, 0.1], "foreign", rng)
    return scans, truth, foreign


@pytest.fixture(scope="module")
def registered(blob_set):
    scans, _, foreign = blob_set
    return register_scans(scans + [foreign], options=MultiwayOptions(seed=3))


def _poses(result):
    return {s.name: s.model_from_scan for s in result.scans if s.registered}


def test_all_placed_near_their_true_poses_and_the_foreign_scan_reported(blob_set, registered):
    scans, truth, _ = blob_set
    by_name = {s.name: s for s in registered.scans}
    assert not by_name["foreign"].registered
    assert "no verified match" in by_name["foreign"].reason
    err = compare_scan_poses(_poses(registered), truth, {s.name: s.points for s in scans})
    assert err.names == sorted(truth) and not err.missing
    # one-sided bounds: the scans' noise is 20 um at 0.3 m; 0.05 deg is the issue's target
    assert err.rotation_deg.max() < 0.05, err.table()
    assert err.displacement_rms.max() < 5e-5, err.table()
    placed = [(s.name, s.rms, s.overlap) for s in registered.scans if s.registered]
    assert all(0 < rms < 5e-4 and overlap > 0.2 for _, rms, overlap in placed), placed


def test_order_and_rotation_of_the_inputs_do_not_change_the_poses(blob_set, registered):
    scans, _, foreign = blob_set
    rng = np.random.default_rng(11)
    turns = {}
    moved = []
    for s in [*scans, foreign]:
        R = np.eye(4)
        R[:3, :3] = axis_angle_matrix(rng.normal(size=3), rng.uniform(0, np.pi))
        R[:3, 3] = rng.normal(size=3) * 0.1
        turns[s.name] = R
        moved.append(s.transformed(R))
    order = rng.permutation(len(moved))
    again = register_scans([moved[k] for k in order], options=MultiwayOptions(seed=3))
    # the pose of each original scan: model_from_moved @ moved_from_scan
    back = {s.name: s.model_from_scan @ turns[s.name] for s in again.scans if s.registered}
    assert set(back) == set(_poses(registered))
    err = compare_scan_poses(back, _poses(registered), {s.name: s.points for s in scans})
    assert err.rotation_deg.max() < 0.01, err.table()


def test_same_seed_same_bytes(blob_set, registered):
    scans, _, foreign = blob_set
    again = register_scans(scans + [foreign], options=MultiwayOptions(seed=3))
    for a, b in zip(registered.scans, again.scans, strict=True):
        assert a.model_from_scan.tobytes() == b.model_from_scan.tobytes()
        assert (a.rms, a.overlap, a.reason) == (b.rms, b.overlap, b.reason) or \
            (np.isnan(a.rms) and np.isnan(b.rms))


def test_the_fine_alignment_started_on_the_true_poses_stays_there_on_exact_scans():
    # noise-free range images of the blob: every sample lies on the true surface, so the
    # true poses are the answer and whatever the fine alignment moves is its own bias.
    # Measured 0.0075 deg / 12 um (the sampling of a curved surface); a matching band of
    # twice the fine voxel gives 0.033 deg / 25 um, matching one way only 0.027 / 21.
    rng = np.random.default_rng(7)
    mesh = _blob()
    scans, truth = [], {}
    for k, eye in enumerate(_views(8)):
        s, T = _scan(mesh, eye, f"scan_{k:02d}", rng, noise=0.0)
        scans.append(s)
        truth[s.name] = T
    pts = {s.name: s.points for s in scans}
    out = refine_scans(scans, [truth[s.name] for s in scans])
    err = compare_scan_poses({s.name: T for s, T in zip(scans, out, strict=True)}, truth, pts)
    assert err.rotation_deg.max() < 0.015, err.table()
    assert err.displacement_rms.max() < 18e-6, err.table()
    # a converged optimum, not a stall: started half a degree and 0.3 mm off, the same poses
    # to the precision of nearest-neighbour matching (measured 0.0026 deg / 1.4 um)
    nudged = []
    for s in scans:
        N = np.eye(4)
        N[:3, :3] = axis_angle_matrix(rng.normal(size=3), np.radians(0.5))
        N[:3, 3] = rng.normal(size=3) * 3e-4
        nudged.append(truth[s.name] @ N)
    again = refine_scans(scans, nudged)
    same = compare_scan_poses({s.name: T for s, T in zip(scans, again, strict=True)},
                              {s.name: T for s, T in zip(scans, out, strict=True)}, pts)
    assert same.rotation_deg.max() < 0.005 and same.displacement_rms.max() < 3e-6, same.table()


def _sheet(fn, n=60, step=1e-3):
    """A height field z = fn(x, y) seen from above (scanner at +z far away)."""
    y, x = np.mgrid[0:n, 0:n] * step
    x, y = x - x.mean(), y - y.mean()
    z = fn(x, y)
    p = np.stack([x.ravel(), y.ravel(), z.ravel()], 1)
    gy, gx = np.gradient(z, step)
    nrm = np.stack([-gx.ravel(), -gy.ravel(), np.ones(z.size)], 1)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return Oriented(p, nrm, np.tile([0, 0, 1.0], (len(p), 1)))


def test_line_of_sight_rejects_a_surface_seen_from_the_back():
    # z odd in y: turned 180 degrees about x, the sheet lies exactly on itself, but seen
    # from below -- a perfect fit on distances that no pair of scanners could produce
    a = _sheet(lambda x, y: 0.004 * np.sin(300 * y) * (1 + 20 * x))
    flip = np.diag([1.0, -1.0, -1.0, 1.0])
    b = a.transformed(flip)
    v = verify_pair(a, b, np.eye(4), tau=1e-3)
    assert v.overlap > 0.9 and v.rms < 1e-9      # the distances alone would accept it
    assert not v.accepted and "back" in v.reason
    assert verify_pair(a, a, np.eye(4), tau=1e-3).accepted   # the true pair passes


def test_line_of_sight_rejects_a_surface_in_the_space_another_scanner_saw_through():
    a = _sheet(lambda x, y: 0.003 * np.cos(200 * x) * np.sin(150 * y))
    lifted = a.points.copy()
    lifted[a.points[:, 0] > 0.01, 2] += 0.01      # a third of b floats 10 mm in front of a
    b = Oriented(lifted, a.normals, a.sight)
    v = verify_pair(a, b, np.eye(4), tau=1e-3)
    assert v.overlap > 0.5 and v.backfacing == 0  # overlap and normals would accept it
    assert not v.accepted and "block" in v.reason and v.blocking > 0.2


def test_pose_evaluation_recovers_a_known_gauge_despite_one_wrong_scan(blob_set):
    scans, truth, _ = blob_set
    gauge = np.eye(4)
    gauge[:3, :3] = axis_angle_matrix([1, 2, 3], 0.7)
    gauge[:3, 3] = [0.5, -0.2, 1.0]
    est = {n: np.linalg.inv(gauge) @ T for n, T in truth.items()}
    wrong = np.eye(4)
    wrong[:3, :3] = axis_angle_matrix([0, 0, 1], np.radians(5.0))
    est["scan_03"] = est["scan_03"] @ wrong
    err = compare_scan_poses(est, truth, {s.name: s.points for s in scans})
    assert np.allclose(err.gauge, gauge, atol=1e-9)
    k = err.names.index("scan_03")
    assert abs(err.rotation_deg[k] - 5.0) < 1e-9 and not err.inliers[k]
    assert np.all(np.delete(err.rotation_deg, k) < 1e-6)
    assert np.all(np.delete(err.displacement_rms, k) < 1e-9)
    assert rotation_angle_deg(err.gauge[:3, :3] @ gauge[:3, :3].T) < 1e-6


def test_cli_needs_two_scans(tmp_path, blob_set):
    from core.io.range import write_range_grid
    from scanamp.cli import main

    scans, _, _ = blob_set
    f = tmp_path / "one.ply"
    write_range_grid(f, RangeGrid(scans[0].points, scans[0].grid))
    out = tmp_path / "out"
    assert main(["reconstruct", "scans", str(f), "--out", str(out)]) == 2
    assert not out.exists()


def test_pipeline_writes_poses_mesh_and_pictures(tmp_path, blob_set):
    from core.io.range import read_conf, read_poses_json, write_range_grid
    from reconstruct.scans.pipeline import ScansReconConfig, run

    scans, truth, foreign = blob_set
    folder = tmp_path / "scans"
    folder.mkdir()
    for s in [*scans[:5], foreign]:
        write_range_grid(folder / f"{s.name}.ply", RangeGrid(s.points, s.grid))
    out = run(ScansReconConfig(seed=3), [folder], tmp_path / "rec")
    for f in ("mesh.ply", "poses.json", "poses.conf", "report.json", "scans_before.png",
              "scans_after.png", "residuals.png"):
        assert (out / f).is_file(), f
    poses = {p.file: p for p in read_poses_json(out / "poses.json")}
    assert not poses["foreign.ply"].registered and poses["foreign.ply"].reason
    placed = {n: p.model_from_scan for n, p in poses.items() if p.registered}
    assert sorted(placed) == [f"scan_0{k}.ply" for k in range(5)]
    assert {n for n, _ in read_conf(out / "poses.conf")} == set(placed)
    err = compare_scan_poses(placed, {f"{n}.ply": T for n, T in truth.items()},
                             {f"{s.name}.ply": s.points for s in scans})
    assert err.rotation_deg.max() < 0.05, err.table()


def test_an_initial_guess_is_used_and_sets_the_model_frame(tmp_path, blob_set):
    from core.io.range import write_conf, write_range_grid
    from reconstruct.scans.pipeline import ScansReconConfig, run

    scans, truth, _ = blob_set
    folder = tmp_path / "scans"
    folder.mkdir()
    for s in scans[:4]:
        write_range_grid(folder / f"{s.name}.ply", RangeGrid(s.points, s.grid))
    nudge = np.eye(4)
    nudge[:3, :3] = axis_angle_matrix([0, 1, 0], np.radians(2.0))  # a rough guess
    write_conf(tmp_path / "guess.conf", [(f"{n}.ply", T @ nudge) for n, T in truth.items()])
    out = run(ScansReconConfig(seed=3), [folder], tmp_path / "rec", poses=tmp_path / "guess.conf")
    from core.io.range import read_poses_json

    placed = {p.file: p.model_from_scan for p in read_poses_json(out / "poses.json")}
    # the result is in the guess's frame (fixed by the first scan's guess), the relative
    # poses are the scans' own
    assert np.allclose(placed["scan_00.ply"], truth["scan_00"] @ nudge, atol=1e-9)
    err = compare_scan_poses(placed, {f"{n}.ply": T for n, T in truth.items()},
                             {f"{s.name}.ply": s.points for s in scans})
    assert err.rotation_deg.max() < 0.05 and len(err.names) == 4, err.table()
