"""Evaluation against ground truth: closed forms on spheres and boxes, CLI errors."""

import json

import numpy as np
import open3d as o3d
import pytest

from core.io.mesh import read_geometry, write_mesh, write_points
from core.sampling import sample_surface
from reconstruct import EvaluationResult, evaluate
from reconstruct.evaluation.evaluate import TAU_FRACTION, fscore_at
from scanamp.cli import main

N = 30_000  # samples per side: enough for the tolerances below, fast on 2 cores


def sphere(radius, resolution=120):
    return o3d.geometry.TriangleMesh.create_sphere(radius, resolution=resolution)


def box():
    # no symmetry that ICP could slide along
    return o3d.geometry.TriangleMesh.create_box(0.10, 0.06, 0.04)


def test_mesh_against_itself_is_perfect(rng):
    s = sphere(0.05)
    res = evaluate(s, s, rng=rng, max_samples=N)
    assert isinstance(res, EvaluationResult)
    assert res.precision == res.recall == res.fscore == 1.0
    # distances to the surface itself: zero up to Embree's float32 arithmetic
    assert res.hausdorff < 1e-6
    assert res.chamfer == pytest.approx(res.accuracy_mean + res.completeness_mean)
    assert res.overall == pytest.approx(res.chamfer / 2)
    assert res.normal_consistency > 0.99
    assert res.icp_fitness is None and res.icp_reference_from_recon is None


def test_sphere_offset_gives_accuracy_d(rng):
    r, d, res_ = 0.05, 0.002, 200
    res = evaluate(sphere(r, res_), sphere(r + d, res_), tau=2 * d, rng=rng, max_samples=N)
    # Distances are to the other faceted surface: facets sag inside the true sphere by at
    # most ~ r (pi / resolution)^2 = 12 um here (0.6 % of d), so the gap is d within that.
    sag = (r + d) * (np.pi / res_) ** 2
    for value in (res.accuracy_mean, res.accuracy_median, res.completeness_mean,
                  res.completeness_median, res.hausdorff_95):
        assert abs(value - d) < sag
    assert res.fscore == 1.0  # every gap (~d) is within tau = 2d
    assert res.hausdorff_95 <= res.hausdorff < 2 * d
    low = evaluate(sphere(r, 200), sphere(r + d, 200), tau=d / 2, rng=rng, max_samples=N)
    assert low.fscore == 0.0  # and none within d / 2


def test_bias_is_signed_along_the_reference_normal(rng):
    # a reconstruction d inside the reference sphere is -d, outside +d (open3d's spheres
    # are wound outward); the surface-distance protocol reports it, the samples one not
    r, d, res_ = 0.05, 0.002, 200
    sag = (r + d) * (np.pi / res_) ** 2
    inside = evaluate(sphere(r, res_), sphere(r + d, res_), tau=2 * d, rng=rng, max_samples=N)
    outside = evaluate(sphere(r + d, res_), sphere(r, res_), tau=2 * d, rng=rng,
                       max_samples=N)
    assert abs(inside.bias + d) < sag and abs(outside.bias - d) < sag
    assert evaluate(sphere(r, res_), sphere(r + d, res_), tau=2 * d, rng=rng, max_samples=N,
                    distance="samples").bias is None


def test_sample_to_sample_protocol_bias(rng):
    # Tanks and Temples / DTU measure to the nearest *sample*: the gap d comes out larger
    # by about E[l^2] / (2 d) = 1 / (2 pi density d) (l the lateral offset to the nearest
    # sample of a Poisson set), ~ 2 % of d here; faceting as above is 10x smaller.
    r, d = 0.05, 0.002
    res = evaluate(sphere(r, 200), sphere(r + d, 200), tau=2 * d, rng=rng, density=2e6,
                   max_samples=100_000, distance="samples")
    assert res.distance == "samples"
    bias = 1.0 / (2 * np.pi * res.density * d)
    assert bias < 0.05 * d
    for value in (res.accuracy_mean, res.completeness_mean):
        assert d + 0.7 * bias < value < d + 1.3 * bias  # measured 0.93-1.03 bias
    same = evaluate(sphere(r), sphere(r), rng=rng, max_samples=N, distance="samples")
    spacing = 1 / np.sqrt(same.density)
    assert 0.2 * spacing < same.accuracy_mean < spacing  # ~ spacing / 2, not 0


def test_half_sphere_precision_recall_asymmetry(rng):
    r = 0.05
    full = sphere(r)
    v, f = np.asarray(full.vertices), np.asarray(full.triangles)
    upper = f[v[f].mean(axis=1)[:, 2] > 0]
    half = (v, upper)  # a (vertices, triangles) pair is accepted too
    res = evaluate(half, full, rng=rng, max_samples=N)
    assert res.precision > 0.999
    # recall: the upper half plus a band of width tau below the rim, ~ tau / (2 r) of the area
    assert 0.5 - 0.02 < res.recall < 0.5 + res.tau / (2 * r) + 0.02
    assert res.fscore == pytest.approx(2 * res.precision * res.recall
                                       / (res.precision + res.recall))
    assert res.completeness_mean > 10 * res.accuracy_mean

    # restricting the reference to what was "seen" (z > 0) restores recall
    seen = evaluate(half, full, rng=np.random.default_rng(1), max_samples=N,
                    reference_mask=lambda p: p[:, 2] > 0)
    assert seen.recall > 0.999 and seen.precision > 0.999
    assert seen.n_reference_samples < 0.55 * res.n_reference_samples


def test_icp_recovers_shift(rng):
    gt = box()
    tau = TAU_FRACTION * np.linalg.norm([0.10, 0.06, 0.04])
    shift = np.array([1.2, -0.8, 0.6]) * tau
    moved = o3d.geometry.TriangleMesh(gt).translate(shift)
    raw = evaluate(moved, gt, rng=np.random.default_rng(3), max_samples=N)
    res = evaluate(moved, gt, icp=True, rng=np.random.default_rng(3), max_samples=N)
    t = np.asarray(res.icp_reference_from_recon)
    assert np.allclose(t[:3, 3], -shift, atol=0.05 * np.linalg.norm(shift))
    assert np.allclose(t[:3, :3], np.eye(3), atol=1e-3)
    assert res.fscore > 0.999 > raw.fscore
    assert res.icp_fitness > 0.99
    assert "alignment fitness" in res.table() and res.alignment["method"] == "icp"


def test_point_cloud_path(tmp_path, rng):
    gt = sphere(0.05)
    v, f = np.asarray(gt.vertices), np.asarray(gt.triangles)
    pts, nrm = sample_surface(v, f, 80_000, rng=rng)
    write_points(tmp_path / "cloud.ply", pts)
    write_points(tmp_path / "cloud_n.ply", pts, normals=nrm)
    write_mesh(tmp_path / "gt.ply", gt)
    cloud = read_geometry(tmp_path / "cloud.ply")
    assert isinstance(cloud, o3d.geometry.PointCloud)
    assert isinstance(read_geometry(tmp_path / "gt.ply"), o3d.geometry.TriangleMesh)
    # a thinned cloud is sparser than the mesh samples: tau = 3 mm keeps its
    # neighbour gaps (~1 mm) well inside
    res = evaluate(cloud, gt, tau=0.003, rng=rng, max_samples=N)
    assert res.fscore > 0.999
    assert res.normal_consistency is None  # the cloud has no normals
    assert res.n_recon_samples <= N  # voxel-thinned, then capped
    with_n = evaluate(read_geometry(tmp_path / "cloud_n.ply"), gt, tau=0.003, rng=rng,
                      max_samples=N)
    assert with_n.normal_consistency > 0.99
    bare = evaluate(pts, gt, tau=0.003, rng=rng, max_samples=N)  # a bare (n, 3) array
    assert bare.fscore > 0.999


def test_default_tau_is_half_percent_of_diagonal(rng):
    res = evaluate(box(), box(), rng=rng, max_samples=5000)
    assert res.tau == pytest.approx(0.005 * np.linalg.norm([0.10, 0.06, 0.04]))
    assert evaluate(box(), box(), tau=0.01, rng=rng, max_samples=5000).tau == 0.01


def test_same_seed_same_numbers():
    s, t = sphere(0.05, 40), sphere(0.051, 40)
    a = evaluate(s, t, rng=np.random.default_rng(7), max_samples=5000).to_dict()
    b = evaluate(s, t, rng=np.random.default_rng(7), max_samples=5000).to_dict()
    c = evaluate(s, t, rng=np.random.default_rng(8), max_samples=5000).to_dict()
    assert a == b
    assert a["accuracy_mean"] != c["accuracy_mean"]


def test_sample_surface_is_area_weighted(rng):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [3, 0, 1], [0, 2, 1.0]])
    f = np.array([[0, 1, 2], [3, 4, 5], [0, 0, 1]])  # areas 0.5, 3, 0 (degenerate)
    pts, nrm = sample_surface(v, f, 20_000, rng=rng)
    upper = np.mean(pts[:, 2] == 1.0)
    # binomial: p = 3 / 3.5, sd = sqrt(p (1 - p) / n) ~ 0.0025; 5 sd
    assert abs(upper - 3 / 3.5) < 0.0125
    assert np.allclose(np.abs(nrm[:, 2]), 1.0)
    low = pts[pts[:, 2] == 0]
    assert np.all(low[:, 0] + low[:, 1] <= 1 + 1e-12) and np.all(low >= 0)


def test_fscore_at():
    assert fscore_at(np.array([0.0, 0.1, 0.3]), np.array([0.1]), 0.1) == pytest.approx(
        (2 / 3, 1.0, 0.8))
    assert fscore_at(np.array([1.0]), np.array([1.0]), 0.5) == (0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="tau"):
        fscore_at(np.array([1.0]), np.array([1.0]), 0)


def test_library_errors_name_the_argument():
    with pytest.raises(ValueError, match="^recon"):
        evaluate(np.zeros((0, 3)), box())
    with pytest.raises(ValueError, match="^reference"):
        evaluate(box(), (np.zeros((3, 3)), np.array([[0, 1, 2]])))  # zero area
    with pytest.raises(ValueError, match="reference_mask"):
        evaluate(box(), box(), max_samples=1000, reference_mask=lambda p: np.zeros(len(p), bool))


# ----------------------------------------------------------------------------- CLI
def test_cli_table_and_json(tmp_path, capsys):
    write_mesh(tmp_path / "gt.ply", sphere(0.05, 40))
    out = tmp_path / "res" / "eval.json"
    code = main(["evaluate", str(tmp_path / "gt.ply"), "--reference", str(tmp_path / "gt.ply"),
                 "--json", str(out), "--max-samples", "5000", "--seed", "3"])
    assert code == 0
    table = capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["fscore"] == 1.0 and data["reference"].endswith("gt.ply")
    assert f"{data['tau']:.6g} m" in table and "F-score" in table
    assert data["normal_consistency"] > 0.99


EMPTY_PLY = ("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
             "property float z\nelement face 0\nproperty list uchar int vertex_indices\n"
             "end_header\n")
FLAT_PLY = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
            "end_header\n0 0 0\n1 1 1\n2 2 2\n3 0 1 2\n")


@pytest.mark.parametrize("kind", ["missing", "corrupt", "empty", "degenerate", "suffix"])
def test_cli_bad_input(tmp_path, capfd, kind):
    gt = tmp_path / "gt.ply"
    write_mesh(gt, sphere(0.05, 20))
    bad = tmp_path / {"suffix": "recon.txt"}.get(kind, "recon.ply")
    if kind == "corrupt":
        bad.write_bytes(b"ply\nformat garbage\n\x00\x01\x02")
    elif kind == "empty":
        bad.write_text(EMPTY_PLY)
    elif kind == "degenerate":
        bad.write_text(FLAT_PLY)
    elif kind == "suffix":
        bad.write_text("1 2 3\n")
    out = tmp_path / "eval.json"
    capfd.readouterr()
    code = main(["evaluate", str(bad), "--reference", str(gt), "--json", str(out)])
    captured = capfd.readouterr()
    assert code == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and str(bad) in lines[0]
    assert "Traceback" not in captured.err and captured.out == ""
    assert not out.exists() and list(tmp_path.glob(".eval*")) == []


def test_cli_bad_tau(tmp_path, capfd):
    write_mesh(tmp_path / "gt.ply", sphere(0.05, 20))
    code = main(["evaluate", str(tmp_path / "gt.ply"), "--reference", str(tmp_path / "gt.ply"),
                 "--tau", "-1"])
    err = capfd.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--tau" in err[0]
