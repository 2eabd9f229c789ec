"""The sparse stage's escalation (issue 32): the cheap default first; the stronger steps
(reconstruct.sfm.escalate) only for the views it left out, which come back registered
where they belong or are named in report.json with why."""

import json
import shutil

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from reconstruct.evaluation.sim3 import Sim3
from reconstruct.sfm.escalate import ring_pairs, similarity_from_common_views

HARD = "0005.png"


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    from data_synth.fixtures import sfm_capture

    return sfm_capture(tmp_path_factory.mktemp("esc"))


def _folder(capture, folder, *, hard: bool):
    """The capture's photos in a plain folder; with ``hard``, one of them blurred and its
    contrast cut to 8 % (a dim, flat shot: the default SIFT finds nothing in it)."""
    folder.mkdir()
    for p in sorted((capture / "images").glob("*.png")):
        if hard and p.name == HARD:
            im = cv2.GaussianBlur(cv2.imread(str(p)).astype(np.float32), (0, 0), 1.0)
            im = (im - im.mean()) * 0.08 + im.mean()
            cv2.imwrite(str(folder / p.name), np.clip(im, 0, 255).astype(np.uint8))
        else:
            shutil.copy(p, folder / p.name)
    return folder


def _run(folder, out, **kw):
    from reconstruct.sfm.pipeline import SfmConfig, run

    return run(SfmConfig(dense=False, num_threads=2, **kw), folder, out).report


def test_a_low_texture_view_is_recovered_where_it_belongs(capture, tmp_path):
    from acquire.camera import Camera
    from reconstruct.camera_files import read_cameras
    from reconstruct.evaluation.sim3 import align_cameras

    folder = _folder(capture, tmp_path / "photos", hard=True)
    default = _run(folder, tmp_path / "default", escalate=False)
    assert default["registered"] == 11 and default["escalation"] is None
    why = default["failed_images"][HARD]
    assert why.startswith("no texture") and "registered view" in why
    rep = _run(folder, tmp_path / "rec")
    esc = rep["escalation"]
    assert esc["entered_because"].startswith("11 of 12")
    assert [s["step"] for s in esc["steps"][:2]] == ["stronger features", "guided matching"]
    _check_epipolar_consistency(tmp_path / "rec")
    if HARD in rep["failed_images"]:  # not recovered: then named, with the matches it had
        assert "inlier matches" in rep["failed_images"][HARD]
        return
    assert rep["registered"] == 12
    # recovered where it belongs: every camera within 0.5 degrees of the truth after Sim(3)
    truth = json.loads((capture / "capture.json").read_text())["ground_truth"]["cameras"]
    est = read_cameras(tmp_path / "rec" / "sparse" / "0")
    errs = align_cameras({n: c.cam_from_world for n, c in est.items()},
                         {n.split("/")[-1]: Camera.from_dict(c).cam_from_world
                          for n, c in truth.items()})
    assert errs.rotation_deg.max() < 0.5, dict(zip(errs.names, errs.rotation_deg, strict=True))


def _check_epipolar_consistency(out):
    """The restarts' yardstick: a model's cameras explain the verified matches (a mean
    squared Sampson distance well under a pixel), a camera turned by 2 degrees does not,
    and each match costs at most the cap (MSAC)."""
    import pycolmap

    from reconstruct.sfm.escalate import epipolar_consistency

    model = pycolmap.Reconstruction(str(out / "sparse" / "0"))
    db = out / "colmap" / "database.db"
    good = epipolar_consistency(model, db)
    frame = model.images[sorted(model.reg_image_ids())[0]].frame
    pose = frame.rig_from_world
    turn = pycolmap.Rotation3d(np.array([0.0, np.radians(2.0), 0.0]))
    frame.rig_from_world = pycolmap.Rigid3d(turn * pose.rotation, pose.translation)
    bad = epipolar_consistency(model, db)
    assert good < 1.0 and bad > 2 * good, (good, bad)
    assert epipolar_consistency(model, db, max_error=0.5) <= 0.25 + 1e-12


@pytest.fixture(scope="module")
def plain(capture, tmp_path_factory):
    """The capture's photos as they are, reconstructed once: (folder, output, report)."""
    root = tmp_path_factory.mktemp("plain")
    folder = _folder(capture, root / "photos", hard=False)
    return folder, root / "rec", _run(folder, root / "rec")


def test_no_escalation_when_the_default_registers_everything(plain):
    rep = plain[2]
    assert rep["registered"] == 12 and rep["failed_images"] == {}
    assert rep["escalation"] is None and rep["timings"]["escalate"] == 0.0


def test_the_refinement_straightens_a_kinked_join(plain, tmp_path):
    """Half of the ring turned 8 degrees about the camera where it joins the other half
    (what a merge of two sub-models leaves): the refinement brings every camera back
    within 0.3 degrees of the others, and its last round keeps no observation beyond
    4 px. (On this well-connected fixture the former 4 px rounds do so too; on the dino
    ring's joins they did not: docs/sfm.md.)"""
    import pycolmap

    from reconstruct.sfm.escalate import refine

    folder, out, _ = plain
    truth = pycolmap.Reconstruction(str(out / "sparse" / "0"))
    rec = pycolmap.Reconstruction(str(out / "sparse" / "0"))
    ims = sorted(rec.images.values(), key=lambda im: im.name)
    pivot = ims[6].projection_center()
    turn = pycolmap.Rotation3d(np.array([0.0, np.radians(8.0), 0.0]))
    about = pycolmap.Rigid3d(turn, pivot - turn * pivot)
    for im in ims[6:]:
        im.frame.rig_from_world = im.frame.rig_from_world * about.inverse()

    def worst_deg(r):
        def rel(m):
            rot = {im.name: im.cam_from_world().rotation.matrix() for im in m.images.values()}
            return {n: R @ rot["0000.png"].T for n, R in rot.items()}
        got, want = rel(r), rel(truth)
        return max(np.degrees(np.arccos(np.clip((np.trace(got[n] @ want[n].T) - 1) / 2,
                                                -1, 1))) for n in want)

    assert worst_deg(rec) > 7.9
    rec = refine(rec, out / "colmap" / "database.db", folder, tmp_path / "refine")
    assert worst_deg(rec) < 0.3, worst_deg(rec)
    assert rec.num_points3D() > 0.8 * truth.num_points3D()
    worst_px = max(rec.points3D[p.point3D_id].error for im in rec.images.values()
                   for p in im.points2D if p.has_point3D())
    assert worst_px <= 4.0 + 1e-6, worst_px


def test_pooled_matches_keep_each_pairs_best_verification(plain, tmp_path):
    """Two copies of one database, a pair's geometry removed from the first and another
    pair's inliers cut in the second: the pool has every pair with its larger set."""
    import pycolmap

    from reconstruct.sfm.escalate import pool_matches

    src = plain[1] / "colmap" / "database.db"
    a, b = tmp_path / "a.db", tmp_path / "b.db"
    shutil.copy2(src, a)
    shutil.copy2(src, b)
    d = pycolmap.Database.open(str(src))
    ids, geoms = d.read_two_view_geometries()
    d.close()
    full = {pycolmap.pair_id_to_image_pair(p): len(g.inlier_matches)
            for p, g in zip(ids, geoms, strict=True)}
    (p1, g1), (p2, g2) = [(pycolmap.pair_id_to_image_pair(p), g)
                          for p, g in zip(ids, geoms, strict=True)][:2]
    da = pycolmap.Database.open(str(a))
    da.delete_two_view_geometry(*p1)
    da.close()
    db_ = pycolmap.Database.open(str(b))
    db_.delete_two_view_geometry(*p2)
    g2.inlier_matches = np.asarray(g2.inlier_matches)[:5]
    db_.write_two_view_geometry(*p2, g2)
    db_.close()
    pooled, replaced = pool_matches([a, b], tmp_path / "pooled.db")
    assert replaced == 1  # only the pair missing from the first came from the second
    d = pycolmap.Database.open(str(pooled))
    got = {pair: len(d.read_two_view_geometry(*pair).inlier_matches) for pair in full}
    d.close()
    assert got == full


def test_the_similarity_between_two_models_comes_back_from_their_common_views():
    rng = np.random.default_rng(0)
    poses = {}
    for k in range(5):
        T = np.eye(4)
        T[:3, :3] = Rotation.random(random_state=k).as_matrix()
        T[:3, 3] = rng.normal(size=3)
        poses[f"v{k}"] = T
    sim = Sim3(2.5, Rotation.random(random_state=9).as_matrix(), np.array([1.0, -2.0, 0.5]))
    # the same cameras in a second model's frame (world_b = sim^-1 world_a)
    inv = Sim3(1 / sim.scale, sim.R.T, -sim.R.T @ sim.t / sim.scale)
    other = {n: inv.apply_cam_from_world(T) for n, T in poses.items() if n != "v0"}
    got, common = similarity_from_common_views(poses, other)
    assert common == ["v1", "v2", "v3", "v4"]
    assert np.isclose(got.scale, 2.5) and np.allclose(got.R, sim.R) and np.allclose(got.t, sim.t)
    one, _ = similarity_from_common_views(poses, {"v1": other["v1"]})
    assert one is None  # one view in common leaves the scale free


def test_ring_pairs_close_the_loop():
    pairs = ring_pairs([f"{i:02d}" for i in range(10)], 2)
    assert ("00", "09") in pairs and ("00", "08") in pairs and ("01", "09") in pairs
    assert len(pairs) == 20 and len(set(pairs)) == 20


def test_a_view_held_by_one_neighbour_is_named_weak(plain):
    """The fixture's ring: every view shares points with at least two others; with the
    points of all but one neighbour of a view deleted, that view is named."""
    import pycolmap

    from reconstruct.sfm.escalate import weakly_tied

    rec = pycolmap.Reconstruction(str(plain[1] / "sparse" / "0"))
    assert weakly_tied(rec) == []
    assert len(weakly_tied(rec, min_points=10 ** 9)) == rec.num_reg_images()
    ids = {im.name: im.image_id for im in rec.images.values()}
    shared = {}
    for pid, p in rec.points3D.items():
        seen = {e.image_id for e in p.track.elements}
        if ids["0005.png"] in seen:
            for other in seen - {ids["0005.png"]}:
                shared.setdefault(other, []).append(pid)
    keep = max(shared, key=lambda k: len(shared[k]))
    for other, pids in shared.items():
        for pid in pids:
            if other != keep and rec.exists_point3D(pid):
                rec.delete_point3D(pid)
    assert "0005.png" in weakly_tied(rec)
