"""The demo end to end at its smallest scale (``scale="test"``), and its helpers."""

import json
import re

import numpy as np
import pytest

from scanamp.cli import main
from scanamp.demo import METHODS, canonical_mesh, run, visible_from_above

# Sanity floor of every method's F-score at the demo's tau (1 % of the scene diagonal):
# at the test scale the three methods reach 0.7 to 0.9; a broken frame transform, a
# failed calibration or a wrong alignment gives well under 0.3.
F_FLOOR = 0.5


@pytest.fixture(scope="module")
def demo_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo") / "out"
    assert main(["demo", "--out", str(out), "--scale", "test", "--seed", "0"]) == 0
    return out


@pytest.fixture(scope="module")
def report(demo_out):
    return json.loads((demo_out / "report.json").read_text())


def test_report_files_exist_and_every_reference_resolves(demo_out, report):
    html = (demo_out / "report.html").read_text()
    refs = set(re.findall(r'(?:src|href)="([^"#]+)"', html))
    assert refs == set(report["files"])
    assert {"report.json", "animate/snow/animation.mp4", "animate/boids/animation.mp4",
            "figures/fscore_vs_tau.png", "figures/error_histograms.png",
            "figures/render_gt.png", "figures/amplify_after.png"} <= refs
    for ref in refs:
        assert not ref.startswith("/") and "://" not in ref, ref  # opens from disk
        assert (demo_out / ref).is_file() and (demo_out / ref).stat().st_size > 0, ref
    for m in METHODS:
        assert f"figures/render_{m}.png" in refs and f"figures/error_{m}.png" in refs
    assert f"tau = {report['tau'] * 1e3:.2f} mm" in html
    assert f"seed {report['seed']}" in html


def test_every_method_is_scored_above_the_floor(report):
    rows = {m["method"]: m for m in report["methods"]}
    assert set(rows) == set(METHODS)
    for name, m in rows.items():
        assert m["ok"], (name, m["error"])
        assert m["fscore"] > F_FLOOR, (name, m["fscore"])
        assert m["points"] > 0 and m["mesh_triangles"] > 0
        assert m["tau"] == pytest.approx(report["tau"])
        assert m["chamfer"] == pytest.approx(m["accuracy_mean"] + m["completeness_mean"])
        # precision at tau bounds the median accuracy: more than half the samples lie within
        assert m["precision"] < 0.5 or m["accuracy_median"] <= m["tau"]
        assert m["seconds"] > 0
    assert report["best"] == max(rows, key=lambda n: rows[n]["fscore"])
    for stage in ("scene", "amplify", "particles", "boids", "total"):
        assert report["timings"][stage] > 0


def test_fscore_curves_agree_with_the_table(report):
    """Two samplings (evaluate's, and the curve's independent one) give the same F at tau."""
    for m in report["methods"]:
        c = report["figures"]["curves"][m["method"]]
        f_at_tau = np.interp(np.log(m["tau"]), np.log(c["tau_m"]), c["fscore"])
        assert f_at_tau == pytest.approx(m["fscore"], abs=0.03), m["method"]
        assert np.all(np.diff(c["fscore"]) >= -1e-12)  # F grows with tau


def test_best_reconstruction_is_amplified_and_animated(demo_out, report):
    from core.io.mesh import read_mesh

    amp = report["amplify"]
    assert [s["kind"] for s in amp["steps"]] == ["clean", "displace", "scatter"]
    cleaned = amp["steps"][0]["after"]["triangles"]
    assert amp["steps"][2]["plants"] > 0                              # the forest was added
    assert amp["steps"][2]["params"]["species"] == "european_beech, scots_pine, sycamore_maple"
    assert amp["output"]["triangles"] > amp["steps"][1]["after"]["triangles"] > cleaned
    assert "before (colour)" in report["figures"]["amplify"]
    best = read_mesh(demo_out / "recon" / f"{report['best']}_aligned.ply")
    assert len(best.triangles) == amp["input"]["triangles"]
    assert report["animations"]["particles"]["frames"] == report["settings"]["snow_frames"]
    assert report["animations"]["boids"]["n"] == report["settings"]["boids"][0]


def test_same_seed_same_table(demo_out, report, tmp_path, monkeypatch):
    from reconstruct.result import ReconstructionResult
    from scanamp.methods import get_method

    sfm = get_method("sfm")

    def no_capture(bundle, config, out_dir, **kw):
        return out_dir

    def sfm_fails(config, inputs, out_dir, **kw):
        return ReconstructionResult(out_dir, {"registered": 2}, ok=False,
                                    message="registered 2 of 12 images")

    # a method whose algorithm fails (reached through the registry, as the demo reaches
    # every method) is recorded in its row and the demo goes on
    monkeypatch.setattr(sfm, "capture", no_capture)
    monkeypatch.setattr(sfm, "reconstruct", sfm_fails)
    again = run(tmp_path / "again", seed=0, scale="test", methods=("laser", "sfm"))
    assert again["methods"][1] == {"method": "sfm", "ok": False,
                                   "error": "sfm failed: registered 2 of 12 images"}
    assert again["best"] == "laser"
    assert "failed: sfm failed" in (tmp_path / "again" / "report.html").read_text()
    # scene and capture: identical bytes
    for rel in ("scene/mesh.ply", "scene/scene.toml", "captures/laser/capture.json",
                "captures/laser/images/scan_0005.png"):
        assert (tmp_path / "again" / rel).read_bytes() == (demo_out / rel).read_bytes(), rel
    a = next(m for m in report["methods"] if m["method"] == "laser")
    b = again["methods"][0]
    assert b["points"] == a["points"]
    # the demo runs OpenCV on one thread so calibrations repeat exactly; only Open3D's
    # multi-threaded ICP may differ in the last bit
    for key in ("fscore", "precision", "recall", "fscore_unaligned"):
        assert b[key] == pytest.approx(a[key], abs=1e-9), key
    for key in ("accuracy_mean", "completeness_mean", "chamfer"):
        assert b[key] == pytest.approx(a[key], rel=1e-9), key
    assert again["tau"] == report["tau"]


def test_scene_demo_rebuilds_bit_for_bit(tmp_path):
    assert main(["scene", "demo", "--out", str(tmp_path / "a")]) == 0
    assert main(["scene", str(tmp_path / "a" / "scene.toml"), "--out", str(tmp_path / "b")]) == 0
    for f in ("mesh.ply", "objects/terrain.ply", "objects/tree.ply", "objects/shell.ply",
              "objects/object.ply", "scene.toml"):
        assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes(), f


def test_demo_scene_fits_the_rigs():
    from data_synth.scenes import build_scene

    b = build_scene("demo")
    v = np.asarray(b.gt_mesh().vertices)
    assert np.linalg.norm(v[:, :2], axis=1).max() < 0.15  # inside the turntable's view
    assert 0.08 < v[:, 2].max() < 0.13
    assert set(b.meshes) == {"terrain", "tree", "shell", "object"}


@pytest.mark.parametrize("argv, field", [
    (["--methods", "laser,lidar"], "--methods"),
    (["--methods", ","], "--methods"),
    (["--seed", "-1"], "--seed"),
])
def test_bad_arguments_exit_2(tmp_path, capsys, argv, field):
    assert main(["demo", "--out", str(tmp_path / "d"), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("error: ") and field in err[-1]
    assert not (tmp_path / "d").exists()


def test_run_rejects_bad_options(tmp_path):
    with pytest.raises(ValueError, match="scale"):
        run(tmp_path / "d", scale="huge")
    with pytest.raises(ValueError, match="methods"):
        run(tmp_path / "d", methods=("laser", "radar"))
    with pytest.raises(ValueError, match="seed"):
        run(tmp_path / "d", seed=-2)


def test_visible_from_above_hides_what_is_covered():
    import open3d as o3d

    from core.meshes import merge_meshes

    ground = o3d.geometry.TriangleMesh.create_box(4.0, 4.0, 0.01).translate((-2, -2, -0.01))
    # a low wide roof: from its centre, even the 20-degree rays meet it (0.1 / tan 20 < 1)
    roof = o3d.geometry.TriangleMesh.create_box(2.0, 2.0, 0.02).translate((-1, -1, 0.1))
    mask = visible_from_above(merge_meshes([ground, roof]))
    pts = np.array([[0.0, 0.0, 0.0],      # under the middle of the roof: hidden
                    [1.9, 1.9, 0.0],      # open ground: visible
                    [0.0, 0.0, 0.12],     # on the roof: visible
                    [0.0, 0.0, -0.005]])  # inside the ground slab: hidden
    assert mask(pts).tolist() == [False, True, True, False]


def test_canonical_mesh_ignores_vertex_and_triangle_order():
    import open3d as o3d

    from core.meshes import make_mesh, mesh_arrays

    v, f = mesh_arrays(o3d.geometry.TriangleMesh.create_sphere(1.0, 8))
    rng = np.random.default_rng(0)
    p = rng.permutation(len(v))
    shuffled = make_mesh(v[p], np.argsort(p)[f][rng.permutation(len(f))])
    a, b = canonical_mesh(make_mesh(v, f)), canonical_mesh(shuffled)
    assert np.array_equal(np.asarray(a.vertices), np.asarray(b.vertices))
    assert np.array_equal(np.asarray(a.triangles), np.asarray(b.triangles))
    a.compute_triangle_normals()
    c = np.asarray(a.vertices)[np.asarray(a.triangles)].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", np.asarray(a.triangle_normals), c) > 0)  # outward kept
