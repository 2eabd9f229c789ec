"""Cleaning a reconstruction: floaters go, holes close, the surface stays where it was,
the faces point outward; sizes are relative, so scale does not change the result."""

import numpy as np
import open3d as o3d
import pytest


def _noisy_scan(scale=1.0, seed=0):
    """A unit-diameter sphere with noise, a hole and 20 small floaters, times ``scale``."""
    rng = np.random.default_rng(seed)
    s = o3d.geometry.TriangleMesh.create_sphere(0.5, resolution=40)
    V = np.asarray(s.vertices)
    V = V + rng.normal(0, 0.002, V.shape) * (V / np.linalg.norm(V, axis=1, keepdims=True))
    F = np.asarray(s.triangles)
    cent = V[F].mean(1)
    F = F[~(cent[:, 2] > 0.485)]  # a cap cut off: a hole at the top
    parts = [(V, F)]
    for _ in range(20):
        t = o3d.geometry.TriangleMesh.create_tetrahedron(0.01)
        c = rng.uniform(-1, 1, 3)
        parts.append((np.asarray(t.vertices) + c, np.asarray(t.triangles)))
    Vs, Fs, off = [], [], 0
    for v, f in parts:
        Vs.append(v)
        Fs.append(f + off)
        off += len(v)
    m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(np.concatenate(Vs) * scale),
                                  o3d.utility.Vector3iVector(np.concatenate(Fs)))
    return m, (V * scale, F)


@pytest.mark.parametrize("scale", [0.01, 1.0, 100.0])
def test_clean_removes_floaters_closes_the_hole_and_stays_on_the_surface(scale):
    from reconstruct.surface.clean import clean_mesh, component_areas

    mesh, (V_in, F_in) = _noisy_scan(scale)
    out, rep = clean_mesh(mesh)
    assert rep["floaters"]["removed"] == 20
    _, areas = component_areas(out)
    assert areas.min() >= 0.01 * areas.sum()  # no component under 1 % of the area
    assert rep["holes"]["boundary_edges_before"] > 0
    assert rep["holes"]["boundary_edges_after"] == 0
    # within 0.5 % of the diagonal of the input (one-sided: cleaned -> kept input surface)
    diag = rep["input"]["diagonal"]
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(V_in.astype(np.float32)),
                        o3d.core.Tensor(F_in.astype(np.uint32)))
    V = np.asarray(out.vertices)
    d = scene.compute_distance(o3d.core.Tensor(V.astype(np.float32))).numpy()
    cap = V[:, 2] > 0.475 * scale  # the filled hole is new surface, not measured
    assert np.percentile(d[~cap], 99) < 0.005 * diag
    # faces outward: normals point away from the centre
    out.compute_triangle_normals()
    Fo = np.asarray(out.triangles)
    c = np.asarray(out.vertices)[Fo].mean(1)
    assert np.mean(np.sum(np.asarray(out.triangle_normals) * c, 1) > 0) > 0.99
    # the remeshing edge is relative: the triangle count does not depend on the scale
    assert 2000 < rep["output"]["triangles"] < 200_000


def test_clean_cli_writes_the_mesh_and_its_report(tmp_path, capsys):
    import json

    from core.io.mesh import read_mesh, write_mesh
    from scanamp.cli import main

    mesh, _ = _noisy_scan()
    write_mesh(tmp_path / "scan.ply", mesh)
    code = main(["-q", "mesh", "clean", str(tmp_path / "scan.ply"), "--out",
                 str(tmp_path / "clean.ply"), "--smooth-steps", "0"])
    assert code == 0, capsys.readouterr().err
    rep = json.loads((tmp_path / "clean.report.json").read_text())
    assert rep["floaters"]["removed"] == 20
    assert len(read_mesh(tmp_path / "clean.ply").triangles) == rep["output"]["triangles"]
    (tmp_path / "empty.ply").write_text("ply\nformat ascii 1.0\nelement vertex 0\n"
                                        "property float x\nproperty float y\nproperty float z\n"
                                        "element face 0\nproperty list uchar int vertex_indices\n"
                                        "end_header\n")
    code = main(["mesh", "clean", str(tmp_path / "empty.ply"), "--out", str(tmp_path / "e.ply")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "empty.ply" in err[0]
    assert not (tmp_path / "e.ply").exists()


def test_clean_is_a_recipe_step(tmp_path):
    """A recipe may start with ``kind = "clean"`` (its defaults are CleanOptions')."""
    from scanamp.amplify import amplify

    recipe = tmp_path / "r.toml"
    recipe.write_text('description = "clean only"\n\n[[step]]\nkind = "clean"\n'
                      'smooth_steps = 0\n')
    mesh, _ = _noisy_scan()
    state, reports = amplify(mesh, recipe)
    from reconstruct.surface.clean import component_areas

    _, areas = component_areas(state.surface)
    rep = reports[0]
    assert len(areas) == 1 and rep["kind"] == "clean"
    assert rep["floaters"]["removed"] == 20 and rep["holes"]["boundary_edges_after"] == 0
    assert rep["params"]["edge_fraction"] == 0.005 and rep["params"]["smooth_steps"] == 0


def test_a_dense_scan_is_decimated_before_remeshing_and_stays_on_its_surface():
    """Far more triangles than the remeshing edge needs (a 200k-triangle scan): the fast
    path decimates first, and the result still lies on the input surface."""
    from reconstruct.surface.clean import CleanOptions, clean_mesh

    s = o3d.geometry.TriangleMesh.create_sphere(0.5, resolution=160)   # 102k triangles
    F = np.asarray(s.triangles)
    out, rep = clean_mesh(s, CleanOptions(edge_fraction=0.02))        # needs about 6k
    assert "decimated_to" in rep and rep["decimated_to"] < len(F) / 2
    r = np.linalg.norm(np.asarray(out.vertices), axis=1)
    assert np.percentile(np.abs(r - 0.5), 99) < 0.005 * rep["input"]["diagonal"]
    assert rep["holes"]["boundary_edges_after"] == 0


def test_the_same_scan_at_any_scale_and_place_is_cleaned_alike():
    """Scale and offset the noisy scan: the cleaned triangles are the same, the vertices
    the same up to that scale and offset (so the steps after it see the same mesh)."""
    from reconstruct.surface.clean import clean_mesh

    a, _ = _noisy_scan(0.01)
    b, _ = _noisy_scan(100.0)
    b.translate((1000.0, -50.0, 7.0))
    oa, _ = clean_mesh(a)
    ob, _ = clean_mesh(b)
    np.testing.assert_array_equal(np.asarray(oa.triangles), np.asarray(ob.triangles))
    va = np.asarray(oa.vertices) * 1e4 + [1000.0, -50.0, 7.0]
    np.testing.assert_allclose(np.asarray(ob.vertices), va, atol=1e-9 * 100)
