import json

import numpy as np
import open3d as o3d
import pytest

from scanamp.cli import main
from simulate.boids import load_recipe, recipe_names


def _run(args, capsys=None):
    code = main(args)
    err = capsys.readouterr().err if capsys else ""
    return code, err


def test_shipped_recipes_load():
    assert {"flock", "swarm", "torus", "parallel"} <= set(recipe_names())
    for name in recipe_names():
        r = load_recipe(name)
        assert r.n >= 1 and r.steps >= 1
    assert load_recipe("swarm").params.bounds is None  # bounds = [] : an open world


def test_cli_writes_series_metrics_animation_report(tmp_path):
    out = tmp_path / "run"
    code, _ = _run(["simulate", "boids", "torus", "--n", "40", "--steps", "12",
                    "--frame-every", "4", "--size", "96x64", "--out", str(out)])
    assert code == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == [".scanamp.json", "animation.mp4", "config.toml", "frames", "metrics.csv",
                     "metrics.png", "report.json", "series.pvd"]
    assert len(list((out / "frames").glob("*.vtp"))) == 4  # steps 0, 4, 8, 12
    rows = (out / "metrics.csv").read_text().splitlines()
    assert rows[0] == "step,time,polarization,milling,nearest_neighbour,groups"
    assert len(rows) == 1 + 13
    rep = json.loads((out / "report.json").read_text())
    assert rep["n"] == 40 and rep["steps"] == 12 and rep["model"] == "couzin"
    assert 0 <= rep["final"]["polarization"] <= 1
    import pyvista as pv

    frame = pv.read(out / "frames" / "frame_00003.vtp")
    assert frame.n_points == 40
    np.testing.assert_allclose(np.linalg.norm(frame.point_data["heading"], axis=1), 1.0)


def test_cli_around_a_mesh_is_deterministic(tmp_path):
    mesh = o3d.geometry.TriangleMesh.create_sphere(radius=1.0, resolution=12)
    path = tmp_path / "m.ply"
    o3d.io.write_triangle_mesh(str(path), mesh)
    outs = []
    for k in range(2):
        out = tmp_path / f"run{k}"
        code, _ = _run(["simulate", "boids", "flock", "--mesh", str(path), "--n", "60",
                        "--steps", "15", "--no-render", "--out", str(out)])
        assert code == 0
        outs.append(out)
    assert (outs[0] / "metrics.csv").read_bytes() == (outs[1] / "metrics.csv").read_bytes()
    assert ((outs[0] / "frames" / "frame_00003.vtp").read_bytes()
            == (outs[1] / "frames" / "frame_00003.vtp").read_bytes())
    rep = json.loads((outs[0] / "report.json").read_text())
    assert rep["mesh"]["triangles"] == len(mesh.triangles)


@pytest.mark.parametrize("toml,needle", [
    ("[boids]\nseparation_radius = -1\n", "boids.separation_radius"),
    ("[boids]\ncohesion_weight = 'a lot'\n", "boids.cohesion_weight"),
    ("[boids]\nmodel = 'couzin'\nzor = 3.0\nzoo = 2.0\n", "boids.zor"),
    ("[boids]\nspeeed = 1.0\n", "boids.speeed"),
    ("[run]\nn = 0\n", "run.n"),
    ("[run]\nobstacle = 'cube'\n", "run.obstacle"),
    ("[boids\n", "malformed TOML"),
])
def test_bad_configs_exit_2_naming_the_field(tmp_path, capsys, toml, needle):
    path = tmp_path / "bad.toml"
    path.write_text(toml)
    code, err = _run(["simulate", "boids", str(path), "--out", str(tmp_path / "o")], capsys)
    assert code == 2
    assert err.startswith("error: ") and needle in err and str(path) in err
    assert not (tmp_path / "o").exists()


def test_bad_recipe_and_mesh_exit_2(tmp_path, capsys):
    code, err = _run(["simulate", "boids", "nonesuch", "--out", str(tmp_path / "o")], capsys)
    assert code == 2 and "flock" in err
    xyz = np.random.default_rng(0).random((10, 3))
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz))
    path = tmp_path / "points.ply"
    o3d.io.write_point_cloud(str(path), pc)
    code, err = _run(["simulate", "boids", "swarm", "--mesh", str(path), "--out",
                      str(tmp_path / "o")], capsys)
    assert code == 2 and "faces" in err
    code, err = _run(["simulate", "boids", "swarm", "--steps", "0", "--out",
                      str(tmp_path / "o")], capsys)
    assert code == 2 and "--steps" in err


def test_glyphs_point_along_heading_and_hide_behind_the_scan():
    from acquire.camera import Camera
    from acquire.render.glyphs import render_glyphs

    cam = Camera.look_at([0, -10, 0], [0, 0, 0], width=120, height=80, fov_deg=30)
    cols = []
    for hx in (1.0, -1.0):
        img = render_glyphs(np.zeros((1, 3)), np.array([[hx, 0, 0]]), cam, size=2.0)
        lit = np.nonzero(img.sum(axis=2) > 0)
        cols.append((lit[1].min(), lit[1].max()))
    # image x grows with world x here: the tip (0.6 size ahead) reaches further than the
    # base (0.4 size behind)
    assert cols[0][1] - 59.5 > 59.5 - cols[0][0]
    assert 59.5 - cols[1][0] > cols[1][1] - 59.5
    hidden = render_glyphs(np.zeros((1, 3)), np.array([[1.0, 0, 0]]), cam, size=2.0,
                           background_depth=np.full((80, 120), 5.0))
    assert hidden.sum() == 0
