"""SfM end to end on a small rendered orbit (one ring of 12 views of 'primitives' at
320x240), plain image folders, and bad input. The heaviest tests of the project: one
capture and one dense reconstruction per session."""

import json
import shutil

import cv2
import numpy as np
import pytest

from acquire.camera import Camera
from scanamp.cli import main


@pytest.fixture(scope="session")
def small_capture(tmp_path_factory):
    from data_synth.fixtures import sfm_capture

    return sfm_capture(tmp_path_factory.mktemp("sfm_fixture"))


@pytest.fixture(scope="session")
def small_recon(small_capture, tmp_path_factory):
    from reconstruct.sfm.pipeline import SfmConfig, run

    out = tmp_path_factory.mktemp("sfm_recon") / "rec"
    res = run(SfmConfig(seed=0, num_threads=1), small_capture, out)
    return res


def test_capture_folder_holds_images_gt_and_transforms(small_capture):
    data = json.loads((small_capture / "capture.json").read_text())
    assert data["kind"] == "sfm" and len(data["frames"]) == 12
    assert data["cameras"]["cam0"]["nominal"] is True
    assert "depth" not in data["frames"][0]  # ground truth only under ground_truth
    tf = json.loads((small_capture / "transforms.json").read_text())
    assert len(tf["frames"]) == 12 and tf["camera_model"] == "OPENCV"


# The reconstruction runs single-threaded: pycolmap's RANSAC and bundle adjustment are then
# bit-for-bit repeatable (test_sparse_stage_is_deterministic), so the figures below are
# fixed numbers, not samples. Measured on this fixture: 12/12 registered, rotation error
# mean 0.065 / max 0.12 deg, ATE 0.10 % of the scene, reprojection 0.18 px, mesh F 0.98
# (the same with all threads, also under CPU load). The bounds leave room for another
# pycolmap/Ceres build without letting a broken pipeline through: a wrong intrinsics
# convention or a mirrored Sim(3) gives degrees and tens of percent.


def test_small_orbit_registers_every_view_accurately(small_recon):
    assert small_recon.ok, small_recon.message
    rep = small_recon.report
    assert rep["registered_fraction"] == 1.0
    poses = rep["metrics"]["poses"]
    # 320x240, 12 views: ~2.5x the measured errors (the 640x480 benchmark asks <= 0.1 deg)
    assert poses["rotation_error_deg"]["mean"] < 0.15
    assert poses["rotation_error_deg"]["max"] < 0.3
    assert poses["ate_fraction_of_scene"] < 0.004
    # SIFT keypoints on rendered images are good to a fraction of a pixel
    assert rep["sparse"]["mean_reprojection_error_px"] < 0.4


def test_small_orbit_dense_mesh_matches_the_scene(small_recon):
    rep = small_recon.report
    out = small_recon.out_dir
    for f in ("mesh.ply", "points.ply", "report.json", "transforms.json",
              "sparse/0/cameras.bin", "sparse/0/images.bin", "sparse/0/points3D.bin",
              "sparse/0/text/cameras.txt", "sparse/0/text/images.txt"):
        assert (out / f).is_file(), f
    # tau = 1% of the scene size, on the surface the cameras saw; measured 0.98 (the
    # benchmark's target at 640x480 is 0.85)
    mesh = rep["metrics"]["mesh"]
    assert mesh["fscore"] > 0.9
    assert mesh["precision"] > 0.9 and mesh["recall"] > 0.9


def _cli(capsys, *argv):
    code = main(list(map(str, argv)))
    err = capsys.readouterr().err.strip().splitlines()
    return code, err


def _jpegs(small_capture, folder, n=12, focal_35mm=None):
    """The capture's images as JPEGs in a plain folder, with an EXIF focal length or none."""
    from PIL import Image

    folder.mkdir()
    for p in sorted((small_capture / "images").glob("*.png"))[:n]:
        exif = Image.Exif()
        if focal_35mm is not None:
            exif.get_ifd(0x8769)[0xA405] = focal_35mm  # FocalLengthIn35mmFilm
        Image.open(p).convert("RGB").save(folder / (p.stem + ".jpg"), quality=95, exif=exif)
    return folder


def _true_focal(small_capture):
    data = json.loads((small_capture / "capture.json").read_text())
    return next(iter(data["ground_truth"]["cameras"].values()))["fx"]


def test_plain_folder_of_jpegs_without_capture_json(small_capture, tmp_path, capsys):
    folder = _jpegs(small_capture, tmp_path / "photos")
    # one blank frame (lens cap on) among the photos: reported by name, the rest goes on
    cv2.imwrite(str(folder / "9999_blank.jpg"), np.full((240, 320, 3), 90, np.uint8))
    code, err = _cli(capsys, "-q", "reconstruct", "sfm", folder, "--out", tmp_path / "rec",
                     "--no-dense", "--num-threads", "1")
    assert code == 0, err
    rep = json.loads((tmp_path / "rec" / "report.json").read_text())
    assert rep["registered"] == 12 and rep["num_images"] == 13
    assert list(rep["failed_images"]) == ["9999_blank.jpg"]
    assert rep["failed_images"]["9999_blank.jpg"].startswith("no texture")
    assert "metrics" not in rep  # no ground truth for a plain folder
    # no EXIF: COLMAP starts from 1.2 x 320 = 384 px; bundle adjustment finds the true
    # 343 px to within 1 % (measured 0.1 %)
    assert "no EXIF focal length: 1.2 x 320 px" in rep["intrinsics_source"]
    f = rep["sparse"]["cameras"]["1"]["params"][0]
    assert abs(f / _true_focal(small_capture) - 1) < 0.01
    # the principal point was ours to estimate: refined or kept at the centre, with the
    # reason, it lands within a pixel of the renders' true one (the image centre)
    (decision,) = rep["principal_point"]
    assert decision["reason"] and decision["views"] == 12
    true = next(iter(json.loads((small_capture / "capture.json").read_text())
                     ["ground_truth"]["cameras"].values()))
    cx, cy = rep["sparse"]["cameras"]["1"]["params"][1:3]
    assert abs(cx - (true["cx"] + 0.5)) < 1.0 and abs(cy - (true["cy"] + 0.5)) < 1.0, \
        decision["reason"]


def test_exif_focal_length_and_camera_option_are_the_starting_intrinsics(small_capture,
                                                                          tmp_path, capsys):
    # COLMAP's EXIF rule: f_px = f_35mm * diag(w, h) / diag(36 mm, 24 mm) = 37 * 400 / 43.27
    folder = _jpegs(small_capture, tmp_path / "exif", n=6, focal_35mm=37)
    code, err = _cli(capsys, "-q", "reconstruct", "sfm", folder, "--out", tmp_path / "r1",
                     "--no-dense", "--num-threads", "1")
    assert code == 0, err
    rep = json.loads((tmp_path / "r1" / "report.json").read_text())
    # 37 x 400 / 43.27 = 342.07 px (COLMAP's own rule, which we now apply ourselves)
    assert "EXIF focal length 342.1 px" in rep["intrinsics_source"]
    assert rep["registered"] == 6
    assert rep["sparse"]["cameras"]["1"]["has_prior_focal_length"] is True
    # --camera wins over EXIF, in COLMAP's pixel convention (centre of pixel 0 at 0.5)
    code, err = _cli(capsys, "-q", "reconstruct", "sfm", folder, "--out", tmp_path / "r2",
                     "--no-dense", "--num-threads", "1", "--camera", "PINHOLE:343,343,160,120")
    assert code == 0, err
    rep = json.loads((tmp_path / "r2" / "report.json").read_text())
    assert rep["intrinsics_source"] == "--camera" and rep["registered"] == 6
    assert rep["sparse"]["cameras"]["1"]["model"] == "PINHOLE"
    # refined from there; 6 views over 150 degrees pin the focal length less tightly than
    # the 12 of the full ring (measured 1.4 % off)
    fx, fy = rep["sparse"]["cameras"]["1"]["params"][:2]
    assert abs(fx / _true_focal(small_capture) - 1) < 0.03
    # --hold-intrinsics: a calibrated camera, exactly as given; without --camera, refused
    code, err = _cli(capsys, "-q", "reconstruct", "sfm", folder, "--out", tmp_path / "r3",
                     "--no-dense", "--num-threads", "1", "--camera", "PINHOLE:340,345,160,120",
                     "--hold-intrinsics")
    assert code == 0, err
    rep = json.loads((tmp_path / "r3" / "report.json").read_text())
    assert rep["intrinsics_source"] == "--camera (held)" and rep["registered"] == 6
    assert rep["sparse"]["cameras"]["1"]["params"] == [340.0, 345.0, 160.0, 120.0]
    code, err = _cli(capsys, "-q", "reconstruct", "sfm", folder, "--out", tmp_path / "r4",
                     "--no-dense", "--hold-intrinsics")
    assert code == 2 and len(err) == 1 and "--hold-intrinsics" in err[0]
    assert not (tmp_path / "r4").exists()


def test_spatial_matcher_without_position_priors_is_a_clear_error(small_capture, tmp_path,
                                                                   capsys):
    code, err = _cli(capsys, "reconstruct", "sfm", _jpegs(small_capture, tmp_path / "p", n=3),
                     "--out", tmp_path / "o", "--matcher", "spatial", "--num-threads", "1")
    assert code == 2 and len(err) == 1 and "position priors" in err[0]
    assert not (tmp_path / "o").exists()


def test_too_few_images_is_one_line_exit_2(small_capture, tmp_path, capsys):
    folder = tmp_path / "two"
    folder.mkdir()
    for p in sorted((small_capture / "images").glob("*.png"))[:2]:
        shutil.copy(p, folder)
    code, err = _cli(capsys, "reconstruct", "sfm", folder, "--out", tmp_path / "o")
    assert code == 2 and len(err) == 1 and "at least 3 images" in err[0]
    assert not (tmp_path / "o").exists()


def test_unreadable_and_truncated_images_are_named(small_capture, tmp_path, capsys):
    folder = _jpegs(small_capture, tmp_path / "bad", n=4)
    (folder / "broken.png").write_bytes(b"not a png")
    code, err = _cli(capsys, "reconstruct", "sfm", folder, "--out", tmp_path / "o")
    assert code == 2 and len(err) == 1 and "broken.png" in err[0]
    assert not (tmp_path / "o").exists()
    (folder / "broken.png").unlink()
    whole = (folder / "0001.jpg").read_bytes()
    (folder / "0001.jpg").write_bytes(whole[: len(whole) // 2])  # a copy cut short
    code, err = _cli(capsys, "reconstruct", "sfm", folder, "--out", tmp_path / "o")
    assert code == 2 and len(err) == 1 and "0001.jpg" in err[0] and "truncated" in err[0]
    assert not (tmp_path / "o").exists()


def test_textureless_images_are_a_clear_error(tmp_path, capsys):
    folder = tmp_path / "flat"
    folder.mkdir()
    for i in range(4):
        cv2.imwrite(str(folder / f"{i}.png"), np.full((120, 160, 3), 40 * i + 20, np.uint8))
    code, err = _cli(capsys, "reconstruct", "sfm", folder, "--out", tmp_path / "o")
    assert code == 2 and len(err) == 1 and "no texture" in err[0]


def test_unrelated_images_do_not_register_and_the_report_says_why(tmp_path, capsys):
    folder = tmp_path / "noise"
    folder.mkdir()
    rng = np.random.default_rng(0)
    for i in range(4):  # textured but unrelated: features, no matches
        img = cv2.GaussianBlur(rng.integers(0, 255, (240, 320), dtype=np.uint8), (0, 0), 1.5)
        cv2.imwrite(str(folder / f"{i}.png"), img)
    code, err = _cli(capsys, "reconstruct", "sfm", folder, "--out", tmp_path / "o")
    assert code == 1 and len(err) == 1 and "did not register" in err[0]
    rep = json.loads((tmp_path / "o" / "report.json").read_text())
    assert rep["ok"] is False and len(rep["failed_images"]) == 4
    assert not (tmp_path / "o" / "mesh.ply").exists()


def test_bad_camera_option_names_the_model(tmp_path, capsys, small_capture):
    code, err = _cli(capsys, "reconstruct", "sfm", small_capture, "--out", tmp_path / "o",
                     "--camera", "PINHOLE:300,160,120")
    assert code == 2 and len(err) == 1 and "PINHOLE expects 4 values" in err[0]


def test_a_camera_that_does_not_move_is_diagnosed(tmp_path, capsys):
    # one view shot five times with fresh sensor noise: every pair's matches sit at the
    # same pixels, which one homography (the identity) explains
    rng = np.random.default_rng(1)
    base = cv2.GaussianBlur(rng.integers(0, 255, (240, 320), dtype=np.uint8), (0, 0), 1.5)
    folder = tmp_path / "static"
    folder.mkdir()
    for i in range(5):
        img = base.astype(float) + rng.normal(0, 2, base.shape)
        cv2.imwrite(str(folder / f"{i}.png"), np.clip(img, 0, 255).astype(np.uint8))
    code, err = _cli(capsys, "reconstruct", "sfm", folder, "--out", tmp_path / "o")
    assert code == 1 and len(err) == 1, err
    assert "no image pair shows camera motion" in err[0] and "debug" not in err[0]
    rep = json.loads((tmp_path / "o" / "report.json").read_text())
    assert len(rep["failed_images"]) == 5
    assert all(why.startswith("no camera motion") for why in rep["failed_images"].values())
    assert "10 planar_or_panoramic" in rep["diagnosis"] or "10 watermark" in rep["diagnosis"]


def test_named_stages_rerun_only_what_changed(small_capture, small_recon, tmp_path):
    """A new trim of the surface re-runs mesh and evaluate, not SIFT or PatchMatch; the
    files of the reused stages come along; --from forces a stage and the later ones."""
    from reconstruct.mvs.fusion import FusionOptions
    from reconstruct.mvs.pipeline import MvsOptions
    from reconstruct.sfm.pipeline import SfmConfig, run

    out = tmp_path / "rec"
    shutil.copytree(small_recon.out_dir, out)
    cfg = SfmConfig(seed=0, num_threads=1,
                    mvs=MvsOptions(fusion=FusionOptions(density_quantile=0.02)))
    res = run(cfg, small_capture, out)
    st = res.report["stages"]
    assert st["reused"] == ["features", "matches", "sparse", "dense"]
    assert st["ran"] == ["fuse", "mesh", "evaluate"]  # fusion's options changed
    for f in ("sparse/0/images.bin", "points.ply", "colmap/database.db"):
        assert (out / f).read_bytes() == (small_recon.out_dir / f).read_bytes(), f
    depth = next((out / "dense").rglob("*.depth.npy"))
    rel = depth.relative_to(out)
    assert depth.read_bytes() == (small_recon.out_dir / rel).read_bytes()
    assert res.report["metrics"]["mesh"]["fscore"] > 0.9
    first = (out / "mesh.ply").read_bytes()
    again = run(cfg, small_capture, out, from_stage="mesh")
    assert again.report["stages"]["ran"] == ["mesh", "evaluate"]
    assert again.report["stages"]["reused"] == ["features", "matches", "sparse", "dense",
                                                "fuse"]
    assert (out / "mesh.ply").read_bytes() == first  # the same inputs, the same bytes


@pytest.mark.slow
def test_same_seed_same_bytes_for_every_output(small_capture, small_recon, tmp_path,
                                               output_differences):
    """Every output of a second run from scratch (the sparse model's binaries, the depth
    maps, the fused points, the mesh) is the same bytes as the first."""
    from reconstruct.sfm.pipeline import SfmConfig, run

    again = run(SfmConfig(seed=0, num_threads=1), small_capture, tmp_path / "rec")
    assert again.ok and small_recon.ok
    assert output_differences(small_recon.out_dir, again.out_dir) == []


def test_strecha_cameras_as_known_cameras_and_as_the_reference(small_capture, tmp_path,
                                                                capsys):
    """A folder of .camera files drives the reconstruction (poses held), and `evaluate
    --poses-reference` of the result against the same folder finds no error."""
    from acquire.camera import Camera
    from reconstruct.camera_files import write_strecha_camera

    data = json.loads((small_capture / "capture.json").read_text())
    cams = tmp_path / "cameras"
    cams.mkdir()
    for n, c in data["ground_truth"]["cameras"].items():
        write_strecha_camera(cams / f"{n.split('/')[-1]}.camera", Camera.from_dict(c))
    code, err = _cli(capsys, "-q", "reconstruct", "sfm", small_capture / "images", "--out",
                     tmp_path / "rec", "--cameras", cams, "--no-dense", "--num-threads", "1")
    assert code == 0, err
    rep = json.loads((tmp_path / "rec" / "report.json").read_text())
    assert rep["registered"] == 12 and rep["intrinsics_source"].startswith("--cameras")
    assert "principal_point" not in rep  # given with the cameras: not ours to move
    code = main(["evaluate", str(tmp_path / "rec"), "--poses-reference", str(cams), "--json",
                 str(tmp_path / "e.json")])
    assert code == 0
    s = json.loads((tmp_path / "e.json").read_text())["summary"]
    assert s["views"] == 12 and s["missing"] == 0
    assert s["rotation_error_deg"]["max"] < 1e-6 and s["centre_error"]["max"] < 1e-6
    assert s["focal_error"]["max"] < 1e-9 and s["principal_point_error_px"]["max"] < 1e-6


def _rotation_error(rec, true) -> float:
    from reconstruct.camera_files import image_cam_from_world
    from reconstruct.evaluation.sim3 import align_cameras

    est = {im.name: image_cam_from_world(im) for im in rec.images.values() if im.has_pose}
    return float(np.median(align_cameras(est, true).rotation_deg))


def test_a_folded_model_is_caught_and_remapped_from_close_pairs(small_capture, small_recon,
                                                                 tmp_path):
    """The sparse stage's self-check (reconstruct.sfm.self_check). The pipeline's model
    passes it (report.json says so); the same model with its second half of views put at
    the poses of the first (a fold: what a symmetric scene can make of a ring) fails it
    with the coincident views named, and the mapper on the pairs close in file order
    gives the ring back where the truth has it, passing the check."""
    import pycolmap

    from reconstruct.sfm.colmap import ColmapOptions
    from reconstruct.sfm.escalate import remap_in_file_order
    from reconstruct.sfm.self_check import check_reconstruction

    rep, out = small_recon.report, small_recon.out_dir
    gt = json.loads((small_capture / "capture.json").read_text())["ground_truth"]
    true = {n: Camera.from_dict(c).cam_from_world for n, c in gt["cameras"].items()}
    assert rep["registered"] == 12 and rep["self_check"]["final"]["ok"]
    assert rep["self_check"]["recovery"] is None and "warnings" not in rep
    database = out / "colmap" / "database.db"
    rec = pycolmap.Reconstruction(str(out / "sparse" / "0"))
    assert _rotation_error(rec, true) < 0.5
    by_name = {im.name: im for im in rec.images.values()}
    names = sorted(by_name)
    for k, n in enumerate(names[6:]):
        rec.frames[by_name[n].frame_id].rig_from_world = by_name[names[k]].cam_from_world()
    folded = check_reconstruction(rec, database)
    assert not folded.ok
    assert sorted(folded.coincident) == [(names[k], names[k + 6]) for k in range(6)]
    assert _rotation_error(rec, true) > 20.0
    again, db, step = remap_in_file_order(database, small_capture, ColmapOptions(num_threads=2),
                                          tmp_path / "ordered", overlap=3)
    assert step["pairs_left_out"] > 0 and step["registered"] == again.num_reg_images() == 12
    assert _rotation_error(again, true) < 0.5
    check = check_reconstruction(again, db)
    assert check.ok and check.explained_share > 0.95 and check.coincident == []
