import json

import numpy as np
import pytest

from scanamp.cli import main
from simulate.recipes import RECIPES, build_particles, load_recipe


def test_every_shipped_recipe_loads():
    """Each shipped recipe builds the system it describes: its emitters, forces, time step
    and sheet, read back from what was built (a recipe parsed wrongly fails here)."""
    from simulate.recipes import build_cloth, procedural_scan

    mesh = procedural_scan(resolution=12)
    for name in RECIPES:
        table, path = load_recipe(name)
        n_forces = len(table.get("forces", []))
        if table["kind"] == "particles":
            ps = build_particles(table, path, mesh=mesh)
            assert len(ps.emitters) == len(table["emitters"]) > 0, name
            assert [e.name for e in ps.emitters][:1] == [
                table["emitters"][0].get("name", "emitter0")], name
            assert ps.dt == pytest.approx(1.0 / table["fps"]), name
            assert ps.substeps == table.get("substeps", 4), name
            f = ps.forces
            built = f.local + f.pairwise + f.springs
        else:
            cloth, substeps = build_cloth(table, path, mesh=mesh)
            spec = table["cloth"]
            assert cloth.x.shape == (spec.get("nx", 20) * spec.get("ny", 20), 3), name
            assert substeps >= 1 and np.isfinite(cloth.x).all(), name
            built = cloth.forces.local + cloth.forces.pairwise
        assert len(built) == n_forces, name


def test_particles_cli_writes_series_and_report(tmp_path):
    out = tmp_path / "fw"
    assert main(["-q", "simulate", "particles", "fountain", "--out", str(out), "--frames", "6",
                 "--size", "64x48"]) == 0
    rep = json.loads((out / "report.json").read_text())
    assert rep["status"] == "ok" and rep["frames"] == 6 and rep["escapes"] == 0
    assert len(list((out / "frames").glob("*.vtp"))) == 6
    assert (out / "series.pvd").read_text().count("<DataSet") == 6
    assert (out / "animation.mp4").stat().st_size > 0
    assert len(list((out / "ply").glob("*.ply"))) == 6


def test_cloth_cli(tmp_path):
    out = tmp_path / "drape"
    assert main(["-q", "simulate", "cloth", "drape", "--out", str(out), "--frames", "2",
                 "--no-render"]) == 0
    rep = json.loads((out / "report.json").read_text())
    assert rep["vertices"] == 28 * 28 and rep["per_frame"][-1]["max_stretch"] < 1.2


def test_bad_recipes_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('kind = "particles"\n[[emitters]]\nrate = -1\n')
    assert main(["simulate", "particles", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and "emitters[0]" in err and "rate" in err
    bad.write_text('kind = "particles"\n[[emitters]]\nspeed = 1\n')
    assert main(["simulate", "particles", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "unknown field" in capsys.readouterr().err
    assert main(["simulate", "particles", "drape", "--out", str(tmp_path / "o")]) == 2
    assert main(["simulate", "particles", "nope", "--out", str(tmp_path / "o")]) == 2
    assert not (tmp_path / "o").exists()


def test_recipe_is_reproducible():
    table, path = load_recipe("smoke")
    a = build_particles(table, path)
    b = build_particles(table, path)
    for _ in range(5):
        a.step_frame()
        b.step_frame()
    np.testing.assert_array_equal(a.state["x"], b.state["x"])
    assert a.count > 0


@pytest.mark.parametrize("mesh", ["missing.ply"])
def test_missing_mesh(tmp_path, mesh, capsys):
    assert main(["simulate", "particles", "snow", "--mesh", str(tmp_path / mesh), "--out",
                 str(tmp_path / "o")]) == 2
    assert "missing.ply" in capsys.readouterr().err


def test_gif_and_a_mesh_without_faces_is_a_warning(tmp_path, caplog):
    import logging

    from core.io.mesh import write_points

    pts = write_points(tmp_path / "cloud.ply", np.random.default_rng(0).uniform(0, 1, (50, 3)))
    out = tmp_path / "gif"
    with caplog.at_level(logging.WARNING):
        assert main(["-q", "simulate", "particles", "fountain", "--mesh", str(pts), "--out",
                     str(out), "--frames", "3", "--size", "32x24", "--gif"]) == 0
    assert "no faces" in caplog.text
    rep = json.loads((out / "report.json").read_text())
    assert rep["status"] == "ok" and rep["collider_closed"] is None
    assert (out / "animation.gif").read_bytes()[:6] in (b"GIF89a", b"GIF87a")
    assert not (out / "animation.mp4").exists()
